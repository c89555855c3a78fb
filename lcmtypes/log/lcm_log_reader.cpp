// SPDX-License-Identifier: MIT
#include "lcmtypes/log/lcm_log_reader.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <optional>

namespace pitmap::lcmlog {

namespace {

constexpr std::uint64_t kHeaderBytes = 4 + 8 + 8 + 4 + 4;

std::uint32_t ReadU32Be(const std::uint8_t* p) {
    return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
           std::uint32_t{p[3]};
}
std::uint64_t ReadU64Be(const std::uint8_t* p) {
    return (std::uint64_t{ReadU32Be(p)} << 32) | ReadU32Be(p + 4);
}

bool PrintableChannel(const std::uint8_t* p, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
        if (p[i] < 0x20 || p[i] > 0x7E) return false;
    }
    return n > 0;
}

}  // namespace

Expected<std::unique_ptr<LcmLogReader>> LcmLogReader::Open(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return Error{path + ": cannot open: " + std::strerror(errno)};
    struct stat st {};
    if (::fstat(fd, &st) != 0) {
        const int e = errno;
        ::close(fd);
        return Error{path + ": cannot stat: " + std::strerror(e)};
    }
    std::unique_ptr<LcmLogReader> r(new LcmLogReader());
    r->size_ = static_cast<std::uint64_t>(st.st_size);
    if (r->size_ > 0) {
        void* m = ::mmap(nullptr, r->size_, PROT_READ, MAP_PRIVATE, fd, 0);
        if (m == MAP_FAILED) {
            const int e = errno;
            ::close(fd);
            return Error{path + ": cannot map: " + std::strerror(e)};
        }
        ::madvise(m, r->size_, MADV_SEQUENTIAL);
        r->data_ = static_cast<const std::uint8_t*>(m);
    }
    ::close(fd);
    return r;
}

LcmLogReader::~LcmLogReader() {
    if (data_ != nullptr) ::munmap(const_cast<std::uint8_t*>(data_), size_);
}

std::optional<LcmLogReader::Header> LcmLogReader::HeaderAt(std::uint64_t pos) const {
    if (pos + kHeaderBytes > size_ || ReadU32Be(data_ + pos) != kLcmSyncWord) return std::nullopt;
    const std::uint8_t* h = data_ + pos;
    Header hd;
    hd.eventnum = static_cast<std::int64_t>(ReadU64Be(h + 4));
    hd.utime = static_cast<std::int64_t>(ReadU64Be(h + 12));
    hd.channel_len = static_cast<std::int32_t>(ReadU32Be(h + 20));
    hd.data_len = static_cast<std::int32_t>(ReadU32Be(h + 24));
    if (hd.channel_len <= 0 || hd.channel_len > kLcmMaxChannelLength || hd.data_len < 0) {
        return std::nullopt;
    }
    const std::uint64_t channel_end =
        pos + kHeaderBytes + static_cast<std::uint64_t>(hd.channel_len);
    if (channel_end > size_ ||
        !PrintableChannel(h + kHeaderBytes, static_cast<std::size_t>(hd.channel_len))) {
        return std::nullopt;
    }
    hd.data_begin = channel_end;
    hd.claimed_end = channel_end + static_cast<std::uint64_t>(hd.data_len);
    return hd;
}

std::uint64_t LcmLogReader::NextPlausibleHeader(std::uint64_t from) const {
    static constexpr std::uint8_t kSync[4] = {0xED, 0xA1, 0xDA, 0x01};
    std::uint64_t q = from;
    while (q + 4 <= size_) {
        const void* hit = ::memmem(data_ + q, size_ - q, kSync, 4);
        if (hit == nullptr) break;
        q = static_cast<std::uint64_t>(static_cast<const std::uint8_t*>(hit) - data_);
        if (HeaderAt(q)) return q;
        ++q;
    }
    return size_;
}

bool LcmLogReader::Next(LcmEvent& ev) {
    while (pos_ + 4 <= size_) {
        if (ReadU32Be(data_ + pos_) != kLcmSyncWord) {
            // Skip to the next sync word in one step, counting the bytes.
            static constexpr std::uint8_t kSync[4] = {0xED, 0xA1, 0xDA, 0x01};
            const void* hit = ::memmem(data_ + pos_, size_ - pos_, kSync, 4);
            const std::uint64_t to =
                hit ? static_cast<std::uint64_t>(static_cast<const std::uint8_t*>(hit) - data_)
                    : size_ - 3;
            counts_.resync_bytes += static_cast<std::int64_t>(to - pos_);
            pos_ = to;
            continue;
        }
        if (pos_ + kHeaderBytes > size_) break;  // truncated header
        const auto hd = HeaderAt(pos_);
        if (!hd) {
            // Impossible lengths or a channel that is not text: resynchronise after this sync.
            ++counts_.corrupt_headers;
            ++pos_;
            ++counts_.resync_bytes;
            continue;
        }
        // The data length is trusted only when the next event starts where it says (or the
        // file ends there). Otherwise it was corrupted, or the next sync word was: the first
        // plausible header after the channel tells which.
        std::uint64_t end = hd->claimed_end;
        const bool lands =
            end == size_ ||
            (end < size_ && (end + 4 > size_ || ReadU32Be(data_ + end) == kLcmSyncWord));
        if (!lands) {
            const std::uint64_t q = NextPlausibleHeader(hd->data_begin);
            if (q < size_ && q < end) {
                // A real event starts inside the claimed span: the length field is wrong. The
                // event's data runs up to that event (exact when only the length was hit;
                // otherwise its lcmtype decode fails and is counted).
                ++counts_.length_repairs;
                end = q;
            } else if (end > size_) {
                break;  // the last event, cut by the end of the file (power cut)
            }
            // else: the length is consistent with the next real event; the sync word after
            // this event was damaged, and the scan resynchronises there.
        }
        ev.eventnum = hd->eventnum;
        ev.utime = hd->utime;
        ev.channel = std::string_view(reinterpret_cast<const char*>(data_ + pos_ + kHeaderBytes),
                                      static_cast<std::size_t>(hd->channel_len));
        ev.data = ByteSpan(data_ + hd->data_begin, static_cast<std::size_t>(end - hd->data_begin));
        pos_ = end;
        ++counts_.events;
        return true;
    }
    if (pos_ < size_) {
        // A partial event (or a partial sync word) at the end of the file.
        ++counts_.truncated_events;
        counts_.truncated_bytes += static_cast<std::int64_t>(size_ - pos_);
        pos_ = size_;
    }
    return false;
}

}  // namespace pitmap::lcmlog
