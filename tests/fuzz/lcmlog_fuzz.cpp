// SPDX-License-Identifier: MIT
// libFuzzer target for reading LCM logs from outside: the bounded log reader
// (lcmtypes/log/lcm_log_reader.hpp) and the wire checks before lcm-gen's decode
// (lcmtypes/log/lcm_wire.hpp), on every message type the shore decodes. Invariants: every event
// lies inside the file and after the previous one, counts add up, a checked decode never throws
// and never holds more elements than the event has bytes.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <pitmap/gps_time_t.hpp>
#include <pitmap/ins_pva_t.hpp>
#include <pitmap/ins_stddev_t.hpp>
#include <pitmap/multibeam_ping_t.hpp>
#include <pitmap/raw_bytes_t.hpp>
#include <string>

#include "lcmtypes/log/lcm_log_reader.hpp"
#include "lcmtypes/log/lcm_wire.hpp"

namespace {

void Check(bool condition) {
    if (!condition) std::abort();
}

template <class T>
void TryDecode(const pitmap::lcmlog::LcmEvent& ev) {
    T msg;
    (void)pitmap::lcmlog::DecodeChecked(msg, ev.data.data(), ev.data.size());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    // The reader maps a file: hand it the input through an anonymous memory file.
    const int fd = ::memfd_create("lcmlog_fuzz", MFD_CLOEXEC);
    if (fd < 0) return 0;
    std::size_t written = 0;
    while (written < size) {
        const ssize_t n = ::write(fd, data + written, size - written);
        if (n <= 0) break;
        written += static_cast<std::size_t>(n);
    }
    const std::string path = "/proc/self/fd/" + std::to_string(fd);
    auto reader = pitmap::lcmlog::LcmLogReader::Open(path);
    Check(reader.ok());
    pitmap::lcmlog::LcmEvent ev;
    std::uint64_t last_end = 0;
    std::int64_t events = 0;
    while ((*reader)->Next(ev)) {
        ++events;
        Check(!ev.channel.empty() && ev.channel.size() <= 256);
        Check((*reader)->position() <= (*reader)->size());
        Check((*reader)->position() >= last_end);
        last_end = (*reader)->position();
        Check(ev.data.size() <= size);
        TryDecode<pitmap::multibeam_ping_t>(ev);
        TryDecode<pitmap::raw_bytes_t>(ev);
        TryDecode<pitmap::ins_pva_t>(ev);
        TryDecode<pitmap::ins_stddev_t>(ev);
        TryDecode<pitmap::gps_time_t>(ev);
    }
    Check((*reader)->position() == (*reader)->size());
    Check((*reader)->counts().events == events);
    ::close(fd);
    return 0;
}
