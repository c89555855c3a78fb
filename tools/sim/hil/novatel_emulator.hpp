// SPDX-License-Identifier: MIT
// Real-time NovAtel receiver port for the HIL rig: a SimulatedReceiver behind a pseudo-terminal
// (COM port, bytes paced at the baud rate, 8N1 = 10 bits per byte; a pty itself ignores the
// baud rate, shared/design/stack.md §6) or behind a TCP ICOM server on a loopback port.
//
// Like a receiver (shared/specs/novatel_oem.md §7): it answers each command line it receives
// with "<OK" or "<ERROR:reason", CR LF, then the port prompt "[COM1]" / "[ICOM1]"; LOG,
// UNLOG and UNLOGALL change which logs it emits (binary logs of the simulated set only:
// INSPVAS, INSPVAX, BESTPOS, INSSTDEV, TIME, RAWIMUSX, INSCONFIG; ONTIME decimates the
// simulated rate, ONNEW/ONCHANGED pass every update, ONCHANGED/ONCE also send the latest copy
// at once); INTERFACEMODE and SERIALCONFIG get <OK and change nothing. Only requested logs (and
// the configured defaults) are emitted. ICOM logs are forgotten when the connection closes;
// COM logs survive an unplug (it is the cable that goes, not the receiver).
//
// Faults (times in survey seconds): garbage bursts, one flipped body byte (bad CRC), pty
// unplug/replug (the pty is closed and a new one made behind the same symlink), TCP drop.
// Every item put on the wire, fault and command is written to the Manifest in wire order.
//
// Failure model: Open() fails with a clear message when openpty is unavailable, the symlink
// path holds something else, or the TCP port is busy. At run time a write error drops the
// connection (recorded) and the port keeps serving.
//
// THREADING: Start() runs one thread that owns the fds, the receiver model and the log table;
// Stop() joins it. stats() may be called from any thread once Stop() returned.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "common/result.hpp"
#include "tools/sim/hil/manifest.hpp"
#include "tools/sim/hil/realtime.hpp"
#include "tools/sim/receiver_sim.hpp"

namespace pitmap::sim::hil {

struct NovatelPortConfig {
    std::string id = "novatel_com1";  // manifest source name
    std::string port_name = "COM1";   // name in prompts and LOG commands
    bool tcp = false;                 // false: pseudo-terminal, true: TCP ICOM server
    std::string pty_link;             // pty: stable symlink to the slave device
    int baud = 460800;                // pty: line rate the writes are paced at, bit/s
    std::string tcp_address = "127.0.0.1";
    int tcp_port = 3001;
    std::vector<std::string> default_logs;  // LOG lines active before any command
    std::vector<double> garbage_times_s, crc_times_s, unplug_times_s, drop_times_s;
    double unplug_s = 1.0;   // how long an unplugged pty stays away, seconds
    std::uint64_t seed = 1;  // garbage bytes

    std::vector<std::string> Validate() const;
};

struct NovatelPortStats {
    std::int64_t frames = 0;  // frames written (corrupt ones included)
    std::int64_t bytes = 0;   // every byte written
    std::int64_t commands = 0;
    std::int64_t commands_ok = 0;
    std::int64_t commands_refused = 0;
    std::int64_t garbage_bursts = 0;
    std::int64_t garbage_bytes = 0;
    std::int64_t crc_errors = 0;
    std::int64_t unplugs = 0;
    std::int64_t tcp_drops = 0;
    std::int64_t connections = 0;  // TCP clients accepted
    std::int64_t lost_frames = 0;  // requested frames due while the port was away
    std::int64_t late_us_max = 0;  // worst lateness of a frame's last byte vs its schedule
};

class NovatelPortEmulator {
public:
    // The references must outlive the emulator.
    NovatelPortEmulator(NovatelPortConfig config,
                        const ScenarioConfig& scenario,
                        const TruthTrajectory& truth,
                        const NavErrorModel& errors,
                        std::int64_t start_utime_gps,
                        const RealTimeBase& time,
                        Manifest& manifest);
    ~NovatelPortEmulator();
    NovatelPortEmulator(const NovatelPortEmulator&) = delete;
    NovatelPortEmulator& operator=(const NovatelPortEmulator&) = delete;

    // Creates the pty (and its symlink) or the listening socket.
    Status Open();
    // Serves until survey time end_s (then drains the line, at most 2 s more).
    void Start(double end_s);
    void Stop();
    NovatelPortStats stats() const { return stats_; }

private:
    struct Item {
        std::vector<std::uint8_t> bytes;
        std::string kind;  // manifest kind
        int message_id = -1;
        std::string command;  // response: the command line answered
        double start_s = 0;   // when its first byte goes out (pty pacing)
        std::size_t written = 0;
    };
    struct ActiveLog {
        bool every_update = true;
        double period_s = 0;
        double last_s = -1e9;
    };

    void Run(double end_s);
    Status CreatePty();
    void ClosePty();
    void CloseClient(const char* why);
    bool Connected() const;
    void Generate(double now);
    void HandleFaults(double now);
    void MoveDueFrames(double now);
    void Push(Item item, double now);
    void ServiceLine(double now);
    void ReadCommands(double now);
    void HandleCommand(const std::string& line, double now);
    std::string ApplyCommand(const std::string& line, double now);
    bool ApplyLog(const std::string& text, double now, std::string& error);
    void Record(const Item& item, double now);

    NovatelPortConfig config_;
    const ScenarioConfig& scenario_;
    const RealTimeBase& time_;
    Manifest& manifest_;
    SimulatedReceiver receiver_;
    NovatelPortStats stats_;

    std::thread thread_;
    std::atomic<bool> stop_{false};

    // Emulator thread only (and Open() before Start()).
    int master_fd_ = -1, slave_fd_ = -1, listen_fd_ = -1, client_fd_ = -1;
    std::map<std::uint16_t, ActiveLog> logs_;
    std::map<std::uint16_t, std::vector<std::uint8_t>> latest_;
    std::deque<EmittedFrame> pending_;
    std::deque<Item> line_;
    double line_free_s_ = -1e9;
    double generated_s_ = 0;
    std::string command_buffer_;
    std::size_t next_garbage_ = 0, next_crc_ = 0, next_unplug_ = 0, next_drop_ = 0;
    int corrupt_pending_ = 0;
    bool unplugging_ = false;
    double unplug_started_s_ = 0;
    double away_until_s_ = -1;
    std::int64_t lost_in_fault_ = 0;
    bool dropping_ = false;
    std::uint64_t rng_state_ = 0;
};

}  // namespace pitmap::sim::hil
