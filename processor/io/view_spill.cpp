// SPDX-License-Identifier: MIT
#include "processor/io/view_spill.hpp"

#include <algorithm>
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

constexpr long long kHeaderBytes = sizeof(kMagic) + sizeof(std::uint64_t) + 1;

// The bytes a sounding takes in each array of the file, in the file's order.
constexpr std::size_t kArrayBytes[] = {sizeof(Eigen::Vector3d),
                                       sizeof(std::uint32_t),
                                       sizeof(std::uint16_t),
                                       sizeof(float),
                                       sizeof(float),
                                       sizeof(std::uint8_t)};

// Where array `a` (index into kArrayBytes) starts in a file of n soundings.
long long ArrayOffset(int a, std::uint64_t n) {
    long long at = kHeaderBytes;
    for (int k = 0; k < a; ++k) at += static_cast<long long>(kArrayBytes[k] * n);
    return at;
}

// Opens a spill file and checks its header and length against what was written.
Expected<File> OpenChecked(const std::string& path, std::uint64_t size, bool with_status) {
    File f(std::fopen(path.c_str(), "rb"));
    if (!f) return Error{path + ": cannot read the view's points: " + std::strerror(errno)};
    char magic[sizeof(kMagic)];
    std::uint64_t n = 0;
    std::uint8_t status = 0;
    if (std::fread(magic, 1, sizeof(magic), f.get()) != sizeof(magic) ||
        std::memcmp(magic, kMagic, sizeof(kMagic)) != 0 ||
        std::fread(&n, sizeof(n), 1, f.get()) != 1 || std::fread(&status, 1, 1, f.get()) != 1 ||
        n != size || (status != 0) != with_status) {
        return Error{path + ": not the view's points this run wrote (header differs)"};
    }
    const long long expected = ArrayOffset(with_status ? 6 : 5, n);
    if (fseeko(f.get(), 0, SEEK_END) != 0) return Error{path + ": cannot seek"};
    const long long length = ftello(f.get());
    if (length < expected) return Error{path + ": the view's points are shorter than written"};
    if (length > expected) return Error{path + ": the view's points are longer than written"};
    return f;
}

// Reads `count` elements of array `a` from sounding `first` on.
template <typename T>
bool ReadAt(
    std::FILE* f, int a, std::uint64_t n, std::size_t first, std::size_t count, std::vector<T>& v) {
    v.resize(count);
    if (count == 0) return true;
    const long long at = ArrayOffset(a, n) + static_cast<long long>(sizeof(T) * first);
    return fseeko(f, at, SEEK_SET) == 0 && std::fread(v.data(), sizeof(T), count, f) == count;
}

}  // namespace

Status SpilledPoints::ReadBlock(std::size_t first,
                                std::size_t count,
                                georef::GeorefPoints& block) const {
    ReleaseAll(block);
    if (path_.empty()) return Error{"the view's points were already read back"};
    if (first > size_) {
        return Error{path_ + ": a block from sounding " + std::to_string(first) + " of " +
                     std::to_string(size_)};
    }
    count = std::min(count, size_ - first);
    auto f = OpenChecked(path_, size_, with_status_);
    if (!f) return f.error();
    const std::uint64_t n = size_;
    const bool ok = ReadAt(f->get(), 0, n, first, count, block.position_world) &&
                    ReadAt(f->get(), 1, n, first, count, block.ping) &&
                    ReadAt(f->get(), 2, n, first, count, block.beam) &&
                    ReadAt(f->get(), 3, n, first, count, block.range_m) &&
                    ReadAt(f->get(), 4, n, first, count, block.angle_rad) &&
                    ReadAt(f->get(), 5, n, first, with_status_ ? count : 0, block.status);
    if (!ok) {
        ReleaseAll(block);
        return Error{path_ + ": cannot read a block of the view's points"};
    }
    return Ok{};
}

Status SpilledPoints::KeepOnly(const std::vector<char>& keep, std::size_t block) {
    if (path_.empty()) return Error{"the view's points were already read back"};
    if (keep.size() != size_) {
        return Error{path_ + ": " + std::to_string(keep.size()) + " verdicts for " +
                     std::to_string(size_) + " soundings"};
    }
    block = std::max<std::size_t>(block, 1);
    const std::uint64_t kept = static_cast<std::uint64_t>(
        std::count_if(keep.begin(), keep.end(), [](char k) { return k != 0; }));
    auto in = OpenChecked(path_, size_, with_status_);
    if (!in) return in.error();
    const std::string next = path_ + ".next";
    File out(std::fopen(next.c_str(), "wb"));
    if (!out) return Error{formats::ErrnoMessage(next, "cannot write the view's points", errno)};
    const std::uint8_t status = with_status_ ? 1 : 0;
    bool ok = std::fwrite(kMagic, 1, sizeof(kMagic), out.get()) == sizeof(kMagic) &&
              std::fwrite(&kept, sizeof(kept), 1, out.get()) == 1 &&
              std::fwrite(&status, 1, 1, out.get()) == 1;
    // Each array in turn, a block at a time: its kept elements appended in order.
    std::vector<char> buffer;
    const int arrays = with_status_ ? 6 : 5;
    for (int a = 0; a < arrays && ok; ++a) {
        const std::size_t bytes = kArrayBytes[a];
        ok = fseeko(in->get(), ArrayOffset(a, size_), SEEK_SET) == 0;
        for (std::size_t first = 0; first < size_ && ok; first += block) {
            const std::size_t count = std::min(block, size_ - first);
            buffer.resize(count * bytes);
            ok = std::fread(buffer.data(), bytes, count, in->get()) == count;
            std::size_t k = 0;
            for (std::size_t j = 0; j < count && ok; ++j) {
                if (keep[first + j] == 0) continue;
                if (k != j)
                    std::memmove(buffer.data() + k * bytes, buffer.data() + j * bytes, bytes);
                ++k;
            }
            ok = ok && (k == 0 || std::fwrite(buffer.data(), bytes, k, out.get()) == k);
        }
    }
    const int err = errno;
    ok = (std::fclose(out.release()) == 0) && ok;
    std::error_code ec;
    if (!ok) {
        std::filesystem::remove(next, ec);
        return Error{formats::ErrnoMessage(next, "cannot write the view's points", err)};
    }
    in->reset();
    std::filesystem::rename(next, path_, ec);
    if (ec) {
        std::filesystem::remove(next, ec);
        return Error{path_ + ": cannot replace the view's points: " + ec.message()};
    }
    size_ = static_cast<std::size_t>(kept);
    return Ok{};
}

Expected<SpillWriter> SpillWriter::Open(const std::string& path,
                                        std::size_t capacity,
                                        bool with_status) {
    File f(std::fopen(path.c_str(), "wb"));
    if (!f) return Error{formats::ErrnoMessage(path, "cannot write the view's points", errno)};
    if (std::fclose(f.release()) != 0) {
        std::error_code ec;
        std::filesystem::remove(path, ec);
        return Error{formats::ErrnoMessage(path, "cannot write the view's points", errno)};
    }
    return SpillWriter(path, capacity, with_status);
}

SpillWriter::SpillWriter(SpillWriter&& other) noexcept
    : path_(std::exchange(other.path_, std::string())),
      capacity_(other.capacity_),
      size_(other.size_),
      with_status_(other.with_status_),
      failed_(other.failed_) {}

SpillWriter& SpillWriter::operator=(SpillWriter&& other) noexcept {
    if (this != &other) {
        if (!path_.empty()) {
            std::error_code ec;
            std::filesystem::remove(path_, ec);
        }
        path_ = std::exchange(other.path_, std::string());
        capacity_ = other.capacity_;
        size_ = other.size_;
        with_status_ = other.with_status_;
        failed_ = other.failed_;
    }
    return *this;
}

SpillWriter::~SpillWriter() {
    if (path_.empty()) return;
    std::error_code ec;
    std::filesystem::remove(path_, ec);
}

namespace {

// Writes `count` elements of array `a` at sounding `first` of a file laid out for n.
template <typename T>
bool WriteAt(std::FILE* f, int a, std::uint64_t n, std::size_t first, const std::vector<T>& v) {
    if (v.empty()) return true;
    const long long at = ArrayOffset(a, n) + static_cast<long long>(sizeof(T) * first);
    return fseeko(f, at, SEEK_SET) == 0 &&
           std::fwrite(v.data(), sizeof(T), v.size(), f) == v.size();
}

// Moves `bytes` bytes from `from` down to `to` (to <= from), front to back.
bool MoveDown(std::FILE* f, long long from, long long to, long long bytes) {
    if (from == to || bytes == 0) return true;
    std::vector<char> buffer(std::min<long long>(bytes, 8 << 20));
    for (long long done = 0; done < bytes;) {
        const auto chunk = static_cast<std::size_t>(
            std::min<long long>(bytes - done, static_cast<long long>(buffer.size())));
        if (fseeko(f, from + done, SEEK_SET) != 0 ||
            std::fread(buffer.data(), 1, chunk, f) != chunk ||
            fseeko(f, to + done, SEEK_SET) != 0 ||
            std::fwrite(buffer.data(), 1, chunk, f) != chunk) {
            return false;
        }
        done += static_cast<long long>(chunk);
    }
    return true;
}

}  // namespace

Status SpillWriter::Append(const georef::GeorefPoints& block) {
    if (path_.empty() || failed_) return Error{"the view's file was finished or failed"};
    const std::size_t n = block.size();
    if (!Consistent(block) || (block.status.size() == n) != (with_status_ || n == 0)) {
        failed_ = true;
        return Error{path_ + ": a block of the view whose arrays differ in length"};
    }
    if (n > capacity_ - size_) {
        failed_ = true;
        return Error{path_ + ": more soundings than the " + std::to_string(capacity_) +
                     " the view was laid out for"};
    }
    File f(std::fopen(path_.c_str(), "r+b"));
    bool ok = static_cast<bool>(f);
    const std::uint64_t cap = capacity_;
    ok = ok && WriteAt(f.get(), 0, cap, size_, block.position_world) &&
         WriteAt(f.get(), 1, cap, size_, block.ping) &&
         WriteAt(f.get(), 2, cap, size_, block.beam) &&
         WriteAt(f.get(), 3, cap, size_, block.range_m) &&
         WriteAt(f.get(), 4, cap, size_, block.angle_rad) &&
         WriteAt(f.get(), 5, cap, size_, block.status);
    const int err = errno;
    ok = f && (std::fclose(f.release()) == 0) && ok;
    if (!ok) {
        failed_ = true;
        return Error{formats::ErrnoMessage(path_, "cannot write the view's points", err)};
    }
    size_ += n;
    return Ok{};
}

Expected<SpilledPoints> SpillWriter::Finish() {
    if (path_.empty() || failed_) return Error{"the view's file was finished or failed"};
    File f(std::fopen(path_.c_str(), "r+b"));
    const std::uint64_t n = size_;
    // As Spill: a view of no soundings has no statuses.
    with_status_ = with_status_ && n > 0;
    const int arrays = with_status_ ? 6 : 5;
    bool ok = static_cast<bool>(f);
    for (int a = 1; a < arrays && ok; ++a) {
        ok = MoveDown(f.get(),
                      ArrayOffset(a, capacity_),
                      ArrayOffset(a, n),
                      static_cast<long long>(kArrayBytes[a] * n));
    }
    const std::uint8_t status = with_status_ ? 1 : 0;
    ok = ok && fseeko(f.get(), 0, SEEK_SET) == 0 &&
         std::fwrite(kMagic, 1, sizeof(kMagic), f.get()) == sizeof(kMagic) &&
         std::fwrite(&n, sizeof(n), 1, f.get()) == 1 && std::fwrite(&status, 1, 1, f.get()) == 1;
    const int err = errno;
    ok = f && (std::fclose(f.release()) == 0) && ok;
    std::error_code ec;
    if (ok)
        std::filesystem::resize_file(
            path_, static_cast<std::uintmax_t>(ArrayOffset(arrays, n)), ec);
    if (!ok || ec) {
        failed_ = true;
        return Error{
            formats::ErrnoMessage(path_, "cannot write the view's points", ok ? EIO : err)};
    }
    return SpilledPoints(std::exchange(path_, std::string()), size_, with_status_);
}

std::string NextViewSpillPath(const std::string& out_dir, const std::string& current) {
    const std::string first = ViewSpillPath(out_dir);
    return current == first ? first + "-next" : first;
}

namespace {

// Copies `bytes` from `in` at `at` to the end of `out`, a buffer of at most `chunk` at a time.
bool CopyBytes(std::FILE* in, long long at, long long bytes, std::FILE* out, std::size_t chunk) {
    if (fseeko(in, at, SEEK_SET) != 0) return false;
    std::vector<char> buffer(static_cast<std::size_t>(
        std::min<long long>(bytes, static_cast<long long>(std::max<std::size_t>(chunk, 1)))));
    while (bytes > 0) {
        const std::size_t n = static_cast<std::size_t>(
            std::min<long long>(bytes, static_cast<long long>(buffer.size())));
        if (std::fread(buffer.data(), 1, n, in) != n || std::fwrite(buffer.data(), 1, n, out) != n)
            return false;
        bytes -= static_cast<long long>(n);
    }
    return true;
}

}  // namespace

Status SpilledPoints::MovePositions(
    std::size_t block, const std::function<void(georef::GeorefPoints&, std::size_t)>& move) {
    if (path_.empty()) return Error{"the view's points were already read back"};
    block = std::max<std::size_t>(block, 1);
    const std::string next = path_ + ".next";
    File out(std::fopen(next.c_str(), "wb"));
    if (!out) return Error{formats::ErrnoMessage(next, "cannot write the view's points", errno)};
    const std::uint64_t n = size_;
    const std::uint8_t status = with_status_ ? 1 : 0;
    bool ok = std::fwrite(kMagic, 1, sizeof(kMagic), out.get()) == sizeof(kMagic) &&
              std::fwrite(&n, sizeof(n), 1, out.get()) == 1 &&
              std::fwrite(&status, 1, 1, out.get()) == 1;
    std::string failure;
    georef::GeorefPoints b;
    for (std::size_t first = 0; first < size_ && ok; first += block) {
        if (auto st = ReadBlock(first, block, b); !st) {
            failure = st.error().message;
            ok = false;
            break;
        }
        const std::size_t count = b.size();
        move(b, first);
        ok = b.position_world.size() == count &&
             std::fwrite(b.position_world.data(), sizeof(Eigen::Vector3d), count, out.get()) ==
                 count;
    }
    ReleaseAll(b);
    // The other arrays as they are, after the positions.
    if (ok) {
        auto in = OpenChecked(path_, size_, with_status_);
        if (in) {
            const long long from = ArrayOffset(1, n);
            const long long to = ArrayOffset(with_status_ ? 6 : 5, n);
            ok = CopyBytes(in->get(), from, to - from, out.get(), block * sizeof(Eigen::Vector3d));
        } else {
            ok = false;
            failure = in.error().message;
        }
    }
    const int err = errno;
    ok = (std::fclose(out.release()) == 0) && ok;
    std::error_code ec;
    if (!ok) {
        std::filesystem::remove(next, ec);
        if (!failure.empty()) return Error{failure};
        return Error{formats::ErrnoMessage(next, "cannot write the view's points", err)};
    }
    std::filesystem::rename(next, path_, ec);
    if (ec) {
        std::filesystem::remove(next, ec);
        return Error{path_ + ": cannot replace the view's points: " + ec.message()};
    }
    return Ok{};
}

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
