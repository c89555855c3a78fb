// SPDX-License-Identifier: MIT
#include "processor/io/svp_files.hpp"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <utility>

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

Expected<std::shared_ptr<const svp::Refraction>> BuildRefraction(
    const survey::RefractionRecord& r) {
    if (!r.enabled()) return std::shared_ptr<const svp::Refraction>();
    auto casts = ReadSoundSpeedFiles(r.svp_files);
    if (!casts) return casts.error();
    if (auto p = svp::Refraction::Check(*casts, r.selection, r.ins_height_above_waterline_m);
        !p.empty()) {
        std::string text;
        for (const auto& line : p) text += (text.empty() ? "" : "\n") + line;
        return Error{text};
    }
    return std::shared_ptr<const svp::Refraction>(std::make_shared<const svp::Refraction>(
        std::move(*casts), r.selection, r.surface_speed, r.ins_height_above_waterline_m));
}

}  // namespace pitmap::proc::io
