// SPDX-License-Identifier: MIT
// `pitmap-sim hil`: a scenario in real time behind the real interfaces, optionally feeding the
// real pitmap-acqd.
//
//   <out>/truth/         the ground truth as `synth` writes it (truth_io.hpp), plus
//                        hil_manifest.jsonl (manifest.hpp) and hil_summary.json
//   <out>/acqd.yaml      the daemon configuration generated for the run (with --acqd)
//   <out>/acqd.out       the daemon's stdout and stderr
//   <out>/log/           the daemon's LCM log and vehicle.yaml (written by the daemon)
//
// The survey starts on a whole Unix second `lead_s` after the call, so the daemon has opened
// its ports and sent its LOG commands before the first epoch; its GPS time is the host's GPS
// time at that moment (the scenario's start_utc is replaced by it in scenario.json).
// Emulators: the NovAtel receiver's COM1 on a pty (INSPVAS, RAWIMUSX, INSPVAX, INSSTDEV,
// INSCONFIG requested by the daemon) and its ICOM1 on TCP (BESTPOS, TIME), the Delta T topside
// on UDP. With --acqd the daemon runs as a child for the duration, then gets SIGTERM; a daemon
// that exits early, fails, or does not stop within stop_timeout_s fails the run.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "tools/sim/hil/faults.hpp"
#include "tools/sim/scenario.hpp"

namespace pitmap::sim::hil {

struct HilOptions {
    std::string out_dir;              // created if missing
    std::string acqd_path;            // "" = emulators only
    double duration_s = 0;            // 0 = the scenario's duration
    std::string pty_link;             // "" = <out>/novatel-com1
    int baud = 460800;                // COM1 line rate, bit/s
    int tcp_port = 3001;              // ICOM1
    int udp_port = 4040;              // the daemon's 83P port
    std::string lcm_url = "memq://";  // the daemon's LCM URL (memq: the log is the output)
    FaultPlan faults;
    std::vector<std::string> default_logs;  // COM1 logs active before any command ("LOG ...")
    double lead_s = 3.0;                    // from the start of the emulators to the first epoch
    double stop_timeout_s = 15.0;           // SIGTERM -> exit of the daemon, seconds
    double truth_rate_hz = 50.0;

    std::vector<std::string> Validate() const;
};

struct HilResult {
    double duration_s = 0;
    std::int64_t start_utime_gps = 0;
    std::int64_t com_frames = 0, icom_frames = 0, pings = 0;
    std::int64_t commands = 0, commands_refused = 0;
    std::int64_t garbage_bursts = 0, crc_errors = 0, unplugs = 0, tcp_drops = 0;
    std::int64_t tcp_connections = 0, lost_frames = 0, ec_frames = 0;
    std::int64_t serial_late_us_max = 0, udp_late_us_max = 0;
    int daemon_exit_code = -1;   // -1 = no daemon
    std::string daemon_problem;  // "" when the daemon ran and stopped cleanly
};

// Runs the scenario; `keep_running` is polled about every 50 ms (false = stop early).
Expected<HilResult> RunHil(ScenarioConfig scenario,
                           const HilOptions& options,
                           const std::function<bool()>& keep_running = {});

}  // namespace pitmap::sim::hil
