// SPDX-License-Identifier: MIT
// Fault injection plan of the HIL rig, parsed from `--faults` and spread over the run.
//
//   --faults garbage=N,crc=N,unplug=N,tcp-drop=N,jitter-ms=X,outage=A:B
//     garbage=N    N bursts of 16..128 bytes that frame nothing, on the serial (pty) port
//     crc=N        N NovAtel frames with one body byte flipped, on the serial port
//     unplug=N     N pty unplugs: the pty is closed, re-created behind the same path after
//                  unplug_s (default 1 s)
//     tcp-drop=N   N drops of the ICOM TCP connection (the receiver forgets ICOM logs)
//     jitter-ms=X  extra transport latency of each datagram, uniform in [0, X] milliseconds
//     outage=A:B   GPS outage of the scenario from A to B seconds after the start
//     unplug-s=X   how long an unplugged pty stays away, seconds
// "none" or an empty string: no faults. Counted events are placed at deterministic times
// inside [settle_s, duration - tail_s), one kind shifted from another so they never coincide.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/result.hpp"

namespace pitmap::sim::hil {

struct FaultPlan {
    int garbage_bursts = 0;
    int crc_errors = 0;
    int unplugs = 0;
    int tcp_drops = 0;
    double jitter_ms = 0;
    double unplug_s = 1.0;
    std::vector<double> outage_s;  // [start, end) pairs, seconds since the start

    // Event times, seconds since the start (filled by Schedule()).
    std::vector<double> garbage_times_s, crc_times_s, unplug_times_s, tcp_drop_times_s;

    // Places the counted events in [settle_s, duration_s - tail_s).
    void Schedule(double duration_s, double settle_s = 4.0, double tail_s = 4.0);
};

// Parses the `--faults` text; an unknown kind or bad value is an error listing the valid ones.
Expected<FaultPlan> ParseFaults(const std::string& text);

}  // namespace pitmap::sim::hil
