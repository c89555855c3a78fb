// SPDX-License-Identifier: MIT
#include "processor/io/svp_files.hpp"

#include <filesystem>
#include <fstream>
#include <iterator>

namespace pitmap::proc::io {

Expected<std::vector<svp::SoundSpeedCast>> ReadSoundSpeedFiles(
    const std::vector<std::string>& paths) {
    constexpr std::uintmax_t kMaxBytes = 64u << 20;
    std::vector<svp::SoundSpeedCast> out;
    for (const std::string& path : paths) {
        std::error_code ec;
        const auto size = std::filesystem::file_size(path, ec);
        if (ec) return Error{path + ": cannot read the sound-velocity file: " + ec.message()};
        if (size > kMaxBytes) return Error{path + ": sound-velocity file larger than 64 MiB"};
        std::ifstream in(path, std::ios::binary);
        if (!in) return Error{path + ": cannot open the sound-velocity file"};
        const std::string text((std::istreambuf_iterator<char>(in)),
                               std::istreambuf_iterator<char>());
        auto casts = svp::ParseCastText(text, path);
        if (!casts) return casts.error();
        for (auto& c : *casts) out.push_back(std::move(c));
        if (out.size() > svp::kMaxCasts) {
            return Error{path + ": more than " + std::to_string(svp::kMaxCasts) + " casts in all"};
        }
    }
    return out;
}

}  // namespace pitmap::proc::io
