// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/clock.hpp"

#include "firmware_host/io/byte_source.hpp"

namespace pitmap::acq {

std::int64_t SystemClock::NowUtime() const {
    return HostNowUtime();
}
std::int64_t SystemClock::MonotonicUs() const {
    return MonotonicNowUs();
}

}  // namespace pitmap::acq
