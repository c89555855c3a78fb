// SPDX-License-Identifier: MIT
#include "processor/io/view_spill.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <utility>
#include <vector>

#include "common/formats/replace_file.hpp"

namespace pitmap::proc::io {

namespace {

constexpr char kMagic[8] = {'P', 'M', 'V', 'I', 'E', 'W', '0', '1'};

struct FileCloser {
    void operator()(std::FILE* f) const {
        if (f != nullptr) std::fclose(f);
    }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

template <typename T>
bool WriteArray(std::FILE* f, const std::vector<T>& v) {
    return v.empty() || std::fwrite(v.data(), sizeof(T), v.size(), f) == v.size();
}

template <typename T>
bool ReadArray(std::FILE* f, std::vector<T>& v, std::size_t n) {
    v.resize(n);
    return n == 0 || std::fread(v.data(), sizeof(T), n, f) == n;
}

// Empties a vector and returns its memory.
template <typename T>
void Release(std::vector<T>& v) {
    std::vector<T>().swap(v);
}

void ReleaseAll(georef::GeorefPoints& p) {
    Release(p.position_world);
    Release(p.ping);
    Release(p.beam);
    Release(p.range_m);
    Release(p.angle_rad);
    Release(p.status);
}

bool Consistent(const georef::GeorefPoints& p) {
    const std::size_t n = p.size();
    return p.ping.size() == n && p.beam.size() == n && p.range_m.size() == n &&
           p.angle_rad.size() == n && (p.status.empty() || p.status.size() == n);
}

}  // namespace

std::string ViewSpillPath(const std::string& out_dir) {
    return (std::filesystem::path(out_dir) / (std::string(formats::kPartialPrefix) + "view_points"))
        .string();
}

Expected<SpilledPoints> SpilledPoints::Spill(georef::GeorefPoints& points,
                                             const std::string& path) {
    if (!Consistent(points)) {
        return Error{path + ": cannot spill the view: its point arrays differ in length"};
    }
    File f(std::fopen(path.c_str(), "wb"));
    if (!f) return Error{formats::ErrnoMessage(path, "cannot write the view's points", errno)};
    const std::uint64_t n = points.size();
    const std::uint8_t with_status = points.status.empty() ? 0 : 1;
    bool ok = std::fwrite(kMagic, 1, sizeof(kMagic), f.get()) == sizeof(kMagic) &&
              std::fwrite(&n, sizeof(n), 1, f.get()) == 1 &&
              std::fwrite(&with_status, 1, 1, f.get()) == 1 &&
              WriteArray(f.get(), points.position_world) && WriteArray(f.get(), points.ping) &&
              WriteArray(f.get(), points.beam) && WriteArray(f.get(), points.range_m) &&
              WriteArray(f.get(), points.angle_rad) && WriteArray(f.get(), points.status);
    const int err = errno;
    ok = (std::fclose(f.release()) == 0) && ok;
    if (!ok) {
        std::error_code ec;
        std::filesystem::remove(path, ec);
        return Error{formats::ErrnoMessage(path, "cannot write the view's points", err)};
    }
    ReleaseAll(points);
    return SpilledPoints(path, static_cast<std::size_t>(n), with_status != 0);
}

SpilledPoints::SpilledPoints(SpilledPoints&& other) noexcept
    : path_(std::exchange(other.path_, std::string())),
      size_(other.size_),
      with_status_(other.with_status_) {}

SpilledPoints& SpilledPoints::operator=(SpilledPoints&& other) noexcept {
    if (this != &other) {
        if (!path_.empty()) {
            std::error_code ec;
            std::filesystem::remove(path_, ec);
        }
        path_ = std::exchange(other.path_, std::string());
        size_ = other.size_;
        with_status_ = other.with_status_;
    }
    return *this;
}

SpilledPoints::~SpilledPoints() {
    if (path_.empty()) return;
    std::error_code ec;
    std::filesystem::remove(path_, ec);
}

Status SpilledPoints::Restore(georef::GeorefPoints& points) {
    ReleaseAll(points);
    if (path_.empty()) return Error{"the view's points were already read back"};
    const std::string path = std::exchange(path_, std::string());
    auto fail = [&](const std::string& what) -> Status {
        ReleaseAll(points);
        std::error_code ec;
        std::filesystem::remove(path, ec);
        return Error{path + ": " + what};
    };
    File f(std::fopen(path.c_str(), "rb"));
    if (!f) return fail(std::string("cannot read the view's points back: ") + std::strerror(errno));
    char magic[sizeof(kMagic)];
    std::uint64_t n = 0;
    std::uint8_t with_status = 0;
    if (std::fread(magic, 1, sizeof(magic), f.get()) != sizeof(magic) ||
        std::memcmp(magic, kMagic, sizeof(kMagic)) != 0 ||
        std::fread(&n, sizeof(n), 1, f.get()) != 1 ||
        std::fread(&with_status, 1, 1, f.get()) != 1 || n != size_ ||
        (with_status != 0) != with_status_) {
        return fail("not the view's points this run wrote (header differs)");
    }
    const std::size_t count = static_cast<std::size_t>(n);
    const bool ok =
        ReadArray(f.get(), points.position_world, count) &&
        ReadArray(f.get(), points.ping, count) && ReadArray(f.get(), points.beam, count) &&
        ReadArray(f.get(), points.range_m, count) && ReadArray(f.get(), points.angle_rad, count) &&
        ReadArray(f.get(), points.status, with_status != 0 ? count : 0);
    if (!ok) return fail("the view's points are shorter than written");
    if (std::fgetc(f.get()) != EOF) return fail("the view's points are longer than written");
    f.reset();
    std::error_code ec;
    std::filesystem::remove(path, ec);
    return Ok{};
}

}  // namespace pitmap::proc::io
