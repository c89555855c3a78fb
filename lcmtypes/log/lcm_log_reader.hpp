// SPDX-License-Identifier: MIT
// A bounded reader of LCM event logs (the lcm-logger format: per event a big-endian sync word
// 0xEDA1DA01, int64 event number, int64 timestamp, int32 channel length, int32 data length,
// channel, data). Written here rather than on lcm::LogFile because that reader asserts on a
// corrupt channel length and allocates whatever data length a corrupt header claims; this one
// resynchronises on the next sync word and counts what it skipped, and reports a truncated last
// event (power cut) instead of failing. An event's data length is trusted only when the next
// sync word is where it says (or the file ends there); a length that points past a real event
// header is repaired to end at that header and counted, so one damaged length field cannot
// swallow the events behind it.
// Thread safety: one reader per thread.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "common/byte_io.hpp"
#include "common/result.hpp"

namespace pitmap::lcmlog {

struct LcmEvent {
    std::int64_t eventnum = 0;
    std::int64_t utime = 0;  // logger receive time, Unix microseconds
    std::string_view channel;
    ByteSpan data;  // valid until the next Next() or the reader's destruction
};

struct LcmLogCounts {
    std::int64_t events = 0;
    std::int64_t corrupt_headers = 0;   // impossible lengths or a channel that is not text
    std::int64_t resync_bytes = 0;      // bytes skipped looking for a sync word
    std::int64_t truncated_events = 0;  // an event cut short by the end of the file
    std::int64_t truncated_bytes = 0;
    std::int64_t length_repairs = 0;  // data lengths that did not land on the next event
};

class LcmLogReader {
public:
    // Maps the file. Fails with a message naming the path.
    static Expected<std::unique_ptr<LcmLogReader>> Open(const std::string& path);
    ~LcmLogReader();
    LcmLogReader(const LcmLogReader&) = delete;
    LcmLogReader& operator=(const LcmLogReader&) = delete;

    // The next event, false at the end of the file.
    bool Next(LcmEvent& event);
    const LcmLogCounts& counts() const { return counts_; }
    std::uint64_t size() const { return size_; }
    std::uint64_t position() const { return pos_; }

private:
    struct Header {
        std::int64_t eventnum = 0;
        std::int64_t utime = 0;
        std::int32_t channel_len = 0;
        std::int32_t data_len = 0;
        std::uint64_t data_begin = 0;   // file offset of the data
        std::uint64_t claimed_end = 0;  // data_begin + data_len (may lie past the file)
    };
    LcmLogReader() = default;
    // A plausible event header at pos: sync word, possible lengths, a text channel that fits.
    std::optional<Header> HeaderAt(std::uint64_t pos) const;
    // Offset of the first plausible header at or after `from`, size() if none.
    std::uint64_t NextPlausibleHeader(std::uint64_t from) const;
    const std::uint8_t* data_ = nullptr;
    std::uint64_t size_ = 0;
    std::uint64_t pos_ = 0;
    LcmLogCounts counts_;
};

inline constexpr std::uint32_t kLcmSyncWord = 0xEDA1DA01u;
inline constexpr std::int32_t kLcmMaxChannelLength = 256;

}  // namespace pitmap::lcmlog
