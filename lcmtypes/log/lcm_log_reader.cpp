// SPDX-License-Identifier: MIT
#include "processor/io/lcm_log_reader.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace pitmap::proc::io {

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

bool LcmLogReader::Next(LcmEvent& ev) {
    while (pos_ + 4 <= size_) {
        if (ReadU32Be(data_ + pos_) != kLcmSyncWord) {
            ++pos_;
            ++counts_.resync_bytes;
            continue;
        }
        if (pos_ + kHeaderBytes > size_) break;  // truncated header
        const std::uint8_t* h = data_ + pos_;
        const auto eventnum = static_cast<std::int64_t>(ReadU64Be(h + 4));
        const auto utime = static_cast<std::int64_t>(ReadU64Be(h + 12));
        const auto channel_len = static_cast<std::int32_t>(ReadU32Be(h + 20));
        const auto data_len = static_cast<std::int32_t>(ReadU32Be(h + 24));
        if (channel_len <= 0 || channel_len > kLcmMaxChannelLength || data_len < 0) {
            ++counts_.corrupt_headers;
            ++pos_;  // resynchronise after this sync word
            continue;
        }
        const std::uint64_t end = pos_ + kHeaderBytes + static_cast<std::uint64_t>(channel_len) +
                                  static_cast<std::uint64_t>(data_len);
        if (end > size_) {
            // Either the last event cut by a power cut, or a corrupt length in the middle: look
            // for a later sync word to tell them apart.
            const void* later = nullptr;
            if (pos_ + 4 < size_) {
                const std::uint8_t sync[4] = {0xED, 0xA1, 0xDA, 0x01};
                later = ::memmem(data_ + pos_ + 4, size_ - pos_ - 4, sync, 4);
            }
            if (later == nullptr) break;
            ++counts_.corrupt_headers;
            ++pos_;
            continue;
        }
        const std::uint8_t* ch = h + kHeaderBytes;
        if (!PrintableChannel(ch, static_cast<std::size_t>(channel_len))) {
            ++counts_.corrupt_headers;
            ++pos_;
            continue;
        }
        ev.eventnum = eventnum;
        ev.utime = utime;
        ev.channel = std::string_view(reinterpret_cast<const char*>(ch),
                                      static_cast<std::size_t>(channel_len));
        ev.data = ByteSpan(ch + channel_len, static_cast<std::size_t>(data_len));
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

}  // namespace pitmap::proc::io
