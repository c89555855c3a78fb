// SPDX-License-Identifier: MIT
// `pitmap-sim synth`: runs a scenario faster than real time and writes
//   <out>/log/    LCM log files exactly as pitmap-acqd would write them (raw chunks of the
//                 NovAtel serial stream and of the 83P datagrams, plus the decoded channels),
//                 rotated by size, and vehicle.yaml (lever arms, nominal boresight)
//   <out>/truth/  the ground truth (tools/sim/truth_io.hpp), with sonar_clock.json and the
//                 truth per beam of the echo artifacts and coarse outliers (artifacts.json,
//                 artifacts.bin; ScenarioConfig::echo_artifacts, tools/sim/echo_artifacts.hpp)
//   <out>/vendor/ with SynthOptions::vendor_files: the files the instruments' own software
//                 would record: <scenario>.gps, the NovAtel binary stream exactly as the
//                 receiver sends it on COM1 (every frame, in emission order), and
//                 <scenario>.83P, the 83P records concatenated as the topside program records
//                 them (the same bytes as its datagrams: header time = topside PC clock; the
//                 data latency field is what was sent live and means nothing in file playback)
//                 and the vehicle.yaml a surveyor keeps beside them (clock offset unknown)
// The NovAtel bytes are chunked as a serial port at `serial_baud` delivers them to 5 ms reads;
// datagrams arrive after the topside's data latency plus network jitter. Host clocks are ideal
// (utime = UTC, utime_gps from a locked model): the daemon's clock estimation is tested by the
// HIL rig, not here.
#pragma once

#include <cstdint>
#include <string>

#include "common/progress.hpp"
#include "common/result.hpp"
#include "tools/sim/scenario.hpp"

namespace pitmap::sim {

struct SynthOptions {
    std::string out_dir;                     // created if missing
    int serial_baud = 460800;                // NovAtel COM port
    std::int64_t rotate_bytes = 64LL << 20;  // log segment size
    int num_threads = 0;                     // sonar ray casting; 0 = hardware concurrency
    double truth_rate_hz = 50.0;             // true trajectory sampling
    bool vendor_files = false;               // also write <out>/vendor/ (see above)
};

struct SynthResult {
    std::int64_t pings = 0;
    std::int64_t novatel_frames = 0;
    std::int64_t novatel_bytes = 0;
    std::int64_t log_events = 0;
    std::int64_t log_bytes = 0;
    int log_files = 0;
    double duration_s = 0;                // simulated
    double track_length_m = 0;            // travelled
    std::int64_t vendor_gps_bytes = 0;    // <out>/vendor/<scenario>.gps (0 without vendor_files)
    std::int64_t vendor_83p_bytes = 0;    // <out>/vendor/<scenario>.83P
    std::int64_t artifact_soundings = 0;  // beams whose range an echo artifact replaced
    double artifact_share = 0;            // of all beams
};

Expected<SynthResult> RunSynth(const ScenarioConfig& scenario,
                               const SynthOptions& options,
                               const ProgressCallback& progress = {});

}  // namespace pitmap::sim
