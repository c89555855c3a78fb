// SPDX-License-Identifier: MIT
// SensorChannel: one byte source of the daemon (a NovAtel port or a Delta T 83P stream) from
// bytes to published LCM messages. sensor_channel.cpp holds what both share (lifecycle,
// dispatch, counters, status); sensor_channel_novatel.cpp and sensor_channel_deltat.cpp the
// protocol handlers.
//
// Per chunk, in this order (style.md "What a daemon component looks like"):
//   1. read with a timeout; the transport stamps utime_host at the read;
//   2. publish the chunk unmodified on RAW_<ID> (raw_bytes_t, with protocol and sequence);
//   3. frame (common/protocol framers), decode, convert (to_lcm.hpp), publish;
//   4. count everything (ChannelCounters, published as channel_status_t by the daemon).
// NovAtel: on every (re)connect (ByteSource::generation() changes) the configured commands
// (abbreviated ASCII, commands.hpp) are sent one at a time; each waits for its <OK / <ERROR
// (command_timeout_ms, resent command_retries times) and the answer is published on
// RESPONSE_<ID> with the command text; refusals and silences are counted. Long headers with
// time status FINE or better, and the body times of short-header INS/IMU logs, feed the host
// clock model (one sample per chunk: the latest GPS time in it, the best lower-envelope point).
// Delta T 83P: a UDP datagram is one record; TCP/file streams go through the stream framer.
// Every ping is stamped through the sonar clock model and published on MULTIBEAM_PING_<ID>
// with utime_gps = GPS time of transmit (the stamp of the header instant plus the v1.10 ping
// latency); before any fix utime_gps = 0 and gps_time_source = TIME_SOURCE_NONE. The rule and
// its inputs (only what RAW_<ID> logs: receive times and the chunk's utime_gps) are
// common/clock/ping_time.hpp, which the shore uses to re-decode the same times. Optional EC
// frames (range, gains from the config) go through ByteSource::Write(), which for UDP sends
// only to the configured head (UdpConfig::reply_to), never to whoever sent last.
// A UDP datagram from a sender not on the allow-list (Chunk::foreign) is published on RAW_<ID>
// with protocol "<protocol>_foreign" (kForeignSuffix) and counted as foreign_datagrams; it is
// never framed or decoded, triggers no EC frame and does not keep the channel RUNNING.
// Datagrams the kernel dropped (ByteSource::kernel_drops()) are counted as kernel_drops and
// noted in the log (rate-limited) whenever the count grows.
// Frame kinds are named as pitmap-inspect names them (so counts compare with the golden
// files): binary "<id>" or "<id>R" (response), "P<id>" proprietary, "#NAME" ASCII, "%NAME"
// short ASCII, "OK" / "ERROR" / "<NAME" abbreviated, "PROMPT", NMEA "$GPGGA"; 83P records
// "83P" and "83P_COMMENT".
//
// THREADING: Start() runs one reader thread that owns the ByteSource, the framers and the
// command state; Stop() joins it (both idempotent, from one controlling thread). Without
// Start(), a test or benchmark drives the same code with RunOnce()/Process() on its own thread.
// counters()/Status() may be called from any thread (ChannelStats mutex). The Publisher,
// TimeKeeper and RateLimitedLog are shared and thread safe.
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/protocol/deltat/ec_frame.hpp"
#include "common/protocol/deltat/stream_framer.hpp"
#include "common/protocol/novatel/framer.hpp"
#include "firmware_host/daemon/channel_stats.hpp"
#include "firmware_host/daemon/clock.hpp"
#include "firmware_host/daemon/publisher.hpp"
#include "firmware_host/daemon/rate_limited_log.hpp"
#include "firmware_host/daemon/time_keeper.hpp"
#include "firmware_host/daemon/to_lcm.hpp"
#include "firmware_host/io/byte_source.hpp"

namespace pitmap::acq {

enum class ChannelProtocol : std::int8_t { kNovatel = 0, kDeltat83P = 1 };
const char* ToString(ChannelProtocol p);  // "novatel", "deltat_83p"

struct EcSteeringConfig {
    bool enabled = false;               // send EC frames to the topside
    protocol::deltat::EcFrame frame{};  // the settings (range_m, start_gain_db, ...)
    int interval_ms = 5000;             // resend period while datagrams arrive, milliseconds
};

struct SensorChannelConfig {
    std::string id;  // channel id, e.g. "novatel_com1"
    ChannelProtocol protocol = ChannelProtocol::kNovatel;
    int read_timeout_ms = 100;     // one Read() wait, milliseconds
    int silent_timeout_ms = 2000;  // no bytes this long while open: SILENT, ms
    int stale_partial_ms = 1000;   // a false sync with frames behind it waits no longer, ms
    std::vector<std::string> setup_commands;  // NovAtel command lines sent on (re)connect,
                                              // e.g. "LOG ICOM1 INSPVAXB ONTIME 0.05"
    int command_timeout_ms = 1000;            // wait for <OK / <ERROR, milliseconds
    int command_retries = 1;                  // resends after a timeout
    ImuContext imu{};                         // IMU type / rates for imu_t
    EcSteeringConfig ec{};                    // Delta T only

    std::vector<std::string> Validate() const;  // every problem, "" prefix-free
};

class SensorChannel {
public:
    // Precondition: config.Validate() is empty. References must outlive the channel.
    SensorChannel(SensorChannelConfig config,
                  ByteSource& source,
                  Publisher& publisher,
                  Clock& clock,
                  TimeKeeper& time,
                  RateLimitedLog* log = nullptr);
    ~SensorChannel();
    SensorChannel(const SensorChannel&) = delete;
    SensorChannel& operator=(const SensorChannel&) = delete;

    // Opens the source (a failure only logs: Read() keeps reopening) and starts the reader
    // thread. Idempotent.
    void Start();
    // Stops and joins the reader thread; flushes a partial frame as truncated. Idempotent.
    void Stop();

    // One iteration of the reader loop: send/retry set-up commands if due, read one chunk
    // (waiting at most read_timeout_ms), process it. False once the source reached its end.
    bool RunOnce();
    // Processes one chunk as if read now (raw publish, framing, decoding, counting).
    void Process(const Chunk& chunk);
    // End of stream: a buffered partial frame gives up its sync as truncated, and the bytes it
    // held are framed again (nothing behind a false header is lost).
    void FlushFramer();

    const SensorChannelConfig& config() const { return config_; }
    ChannelCounters counters() const { return stats_.Get(); }
    // channel_status_t snapshot at the clock's current time.
    pitmap::channel_status_t Status() const;
    bool finished() const { return finished_.load(); }

private:
    void PublishEncoded(std::string_view channel,
                        std::int64_t utime,
                        std::vector<std::uint8_t> data);
    void ProcessNovatel(const Chunk& chunk);
    void DrainNovatel(const Chunk& chunk);
    void DrainDeltat(const Chunk& chunk);
    void RememberChunk(const Chunk& chunk);
    // A stale wait (kStale) or the end of the stream (kTruncated): see FlushFramer.
    void GiveUpPartials(protocol::SkipReason why);
    void HandleNovatelFrame(const protocol::novatel::Frame& frame, const Chunk& chunk);
    void ProcessDeltat(const Chunk& chunk);
    void HandlePing(const protocol::deltat::Ping83P& ping, const Chunk& chunk);
    void CountSkip(const protocol::Skipped& s);
    void PollCommands();
    void SendCurrentCommand();
    void OnResponse(const protocol::novatel::Response& r, std::int64_t utime_host);
    void MaybeSendEc();
    void CheckKernelDrops();
    // Logs through the rate-limited log; true when the line was printed.
    bool Note(const std::string& condition, const std::string& message);

    const SensorChannelConfig config_;
    ByteSource& source_;
    Publisher& publisher_;
    Clock& clock_;
    TimeKeeper& time_;
    RateLimitedLog* log_;
    ChannelStats stats_;

    std::thread thread_;
    std::atomic<bool> stop_{false};
    std::atomic<bool> finished_{false};
    bool running_ = false;

    // Reader thread only.
    std::int64_t seq_ = 0;
    Chunk chunk_;
    Chunk last_chunk_;                  // receive time and peer of the latest chunk (no data)
    std::int64_t chunk_utime_gps_ = 0;  // GPS time of the latest chunk's utime_host as its
                                        // raw_bytes_t logs it (0 = unknown); pings take it
    protocol::novatel::Framer novatel_framer_;
    protocol::deltat::StreamFramer deltat_framer_;
    protocol::deltat::FloatOrderMemory float_memory_;
    protocol::deltat::Ping83P ping_;
    std::int64_t last_bytes_mono_us_ = -1;
    std::int64_t last_clock_host_ = 0;  // last host time fed to the clock model
    std::int64_t chunk_best_gps_ = 0;   // latest valid GPS time in this chunk
    bool chunk_time_invalid_ = false;   // a long header in this chunk had no fine time
    ImuContext imu_;
    std::int64_t last_corrimu_gps_ = 0;
    std::int64_t seen_generation_ = 0;
    std::size_t command_index_ = 0;  // next command; == size(): none pending
    bool command_pending_ = false;
    int command_attempts_ = 0;
    std::int64_t command_sent_mono_us_ = 0;
    std::vector<std::string> command_lines_;  // encoded, CR LF terminated
    std::int64_t last_ec_mono_us_ = -1;
    std::int64_t kernel_drops_checked_ = 0;       // source_.kernel_drops() at the last check
    std::int64_t kernel_drops_noted_ = 0;         // ... at the last printed note
    std::int64_t kernel_drops_note_mono_us_ = 0;  // monotonic time of the last note attempt
};

}  // namespace pitmap::acq
