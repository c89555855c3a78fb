// SPDX-License-Identifier: MIT
// pitmap-acqd data path benchmark: SensorChannel + LcmPublisher (file:// LCM provider) +
// LogWriter on synthetic sensor streams.
//   1. CPU per second of data at nominal rates (INSPVAS 100 Hz + INSPVAX 20 Hz + RAWIMUSX
//      200 Hz + BESTPOS/TIME 1 Hz on a serial-like NovAtel stream in 10 ms chunks, 83P v1.10
//      480-beam pings at 10 Hz), and at 10x those rates, as fast as the code goes; frame loss
//      is checked (frames framed == frames generated, log events == published, no drops).
//   2. Receive-to-logged latency: chunks fed one by one, time from Process() to the log
//      writer having written the chunk's events (write(2) done), p50/p99.
// Usage: pitmap-bench-acqd [output directory, default /tmp]
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <thread>
#include <vector>

#include "common/gps_time.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/novatel/encoder.hpp"
#include "firmware_host/daemon/log_writer.hpp"
#include "firmware_host/daemon/publisher.hpp"
#include "firmware_host/daemon/sensor_channel.hpp"

namespace {

using namespace pitmap;
using namespace pitmap::acq;
namespace nv = protocol::novatel;
namespace dt = protocol::deltat;

double CpuSeconds() {
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_utime.tv_sec + ru.ru_stime.tv_sec +
           (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-6;
}

class ChunkSource final : public ByteSource {
public:
    Status Open() override {
        NoteOpened();
        return Ok{};
    }
    Expected<ReadOutcome> Read(Chunk&, int) override { return ReadOutcome::kEndOfStream; }
    Status Write(std::span<const std::byte>, int) override { return Ok{}; }
    void Close() override {}
    Transport transport() const override { return t_; }
    std::string description() const override { return "bench"; }
    Transport t_ = Transport::kSerial;
};

struct Stream {
    std::vector<Chunk> novatel;  // one per 10 ms
    std::vector<Chunk> pings;
    std::int64_t novatel_frames = 0;
};

nv::Header ShortHeader(std::uint16_t id, std::int64_t gps_us) {
    nv::Header h;
    h.kind = nv::HeaderKind::kShortBinary;
    h.message_id = id;
    h.gps_week = static_cast<std::uint16_t>(gps_us / kMicrosPerWeek);
    h.gps_ms = static_cast<std::uint32_t>((gps_us % kMicrosPerWeek) / 1000);
    return h;
}

Stream Make(double seconds, int rate_x) {
    Stream s;
    const std::int64_t t0_gps = 2300 * kMicrosPerWeek;
    const std::int64_t t0_host = 1'700'000'000'000'000;
    const int ticks = static_cast<int>(seconds * 1000.0 * rate_x);  // 1 ms / rate_x steps
    std::vector<std::uint8_t> buf;
    for (int k = 0; k < ticks; ++k) {
        const std::int64_t us = static_cast<std::int64_t>(k) * 1000 / rate_x;
        const std::int64_t gps = t0_gps + us;
        if (k % 5 == 0) {  // 200 Hz x rate_x
            nv::RawImu m;
            m.header = ShortHeader(nv::msg_id::kRawImuSX, gps);
            m.imu_type = 13;
            m.gps_week = 2300;
            m.gps_seconds = static_cast<double>(us) * 1e-6;
            m.accel_counts = {1000, -2000, 300000};
            m.gyro_counts = {10, 20, -30};
            nv::EncodeBinary(m, buf);
            ++s.novatel_frames;
        }
        if (k % 10 == 0) {  // 100 Hz
            nv::InsPva m;
            m.header = ShortHeader(nv::msg_id::kInsPvaS, gps);
            m.gps_week = 2300;
            m.gps_seconds = static_cast<double>(us) * 1e-6;
            m.latitude_deg = 41.1;
            nv::EncodeBinary(m, buf);
            ++s.novatel_frames;
        }
        if (k % 50 == 0) {  // 20 Hz
            nv::InsPvaX m;
            m.header = ShortHeader(nv::msg_id::kInsPvaX, gps);
            m.header.kind = nv::HeaderKind::kLongBinary;
            m.header.time_status = nv::TimeStatus::kFineSteering;
            nv::EncodeBinary(m, buf);
            ++s.novatel_frames;
        }
        if (k % 1000 == 0) {  // 1 Hz
            nv::BestPos b;
            b.header = ShortHeader(nv::msg_id::kBestPos, gps);
            b.header.kind = nv::HeaderKind::kLongBinary;
            b.header.time_status = nv::TimeStatus::kFineSteering;
            nv::EncodeBinary(b, buf);
            nv::Time t;
            t.header = b.header;
            t.header.message_id = nv::msg_id::kTime;
            nv::EncodeBinary(t, buf);
            s.novatel_frames += 2;
        }
        if (k % 10 == 9) {  // a 10 ms serial chunk
            Chunk c;
            c.data.resize(buf.size());
            std::memcpy(c.data.data(), buf.data(), buf.size());
            c.utime_host = t0_host + us + 2000;
            s.novatel.push_back(std::move(c));
            buf.clear();
        }
        if (k % 100 == 0) {  // 10 Hz pings
            dt::Ping83P p;
            p.format_version = dt::kVersion110;
            dt::SetHeaderTime(p, t0_host + us - 3'000'000);
            p.range_resolution_mm = 10;
            p.ping_number = static_cast<std::uint32_t>(k / 100);
            p.data_latency_us = 20'000;
            p.range_counts.assign(480, 1234);
            p.intensity_included = true;
            p.intensities.assign(480, 77);
            const auto rec = dt::EncodeRecord83P(p);
            Chunk c;
            c.data.resize(rec.size());
            std::memcpy(c.data.data(), rec.data(), rec.size());
            c.utime_host = t0_host + us + 21'000;
            s.pings.push_back(std::move(c));
        }
    }
    return s;
}

SensorChannelConfig NovConfig() {
    SensorChannelConfig c;
    c.id = "nov";
    c.imu.imu_type = 13;
    c.imu.imu_rate_hz = 200.0;
    return c;
}

SensorChannelConfig MbConfig() {
    SensorChannelConfig c;
    c.id = "mb";
    c.protocol = ChannelProtocol::kDeltat83P;
    return c;
}

struct Rig {
    explicit Rig(const std::string& dir)
        : log(LogWriterConfig{.directory = dir, .prefix = "bench", .min_free_bytes = 0}),
          publisher(LcmPublisherConfig{.lcm_url = "file://" + dir + "/lcm.lcmlog?mode=w"}, &log),
          nov(NovConfig(), nov_src, publisher, clock, time),
          mb(MbConfig(), mb_src, publisher, clock, time) {
        mb_src.t_ = Transport::kUdp;
        if (!log.Start() || !publisher.Start()) std::fprintf(stderr, "cannot start the rig\n");
    }
    ~Rig() {
        publisher.Stop();
        log.Stop();
    }
    LogWriter log;
    LcmPublisher publisher;
    ChunkSource nov_src, mb_src;
    SystemClock clock;
    TimeKeeper time;
    SensorChannel nov;
    SensorChannel mb;
};

void Throughput(const std::string& dir, int rate_x, double seconds) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const Stream s = Make(seconds, rate_x);
    Rig rig(dir);
    const double c0 = CpuSeconds();
    const auto w0 = std::chrono::steady_clock::now();
    std::size_t p = 0;
    for (std::size_t i = 0; i < s.novatel.size(); ++i) {
        rig.nov.Process(s.novatel[i]);
        if (p < s.pings.size() && s.pings[p].utime_host <= s.novatel[i].utime_host)
            rig.mb.Process(s.pings[p++]);
    }
    while (p < s.pings.size()) rig.mb.Process(s.pings[p++]);
    rig.publisher.Drain(60'000);
    rig.log.Flush(60'000);
    const double cpu = CpuSeconds() - c0;
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
    const auto nc = rig.nov.counters();
    const auto mc = rig.mb.counters();
    const auto ls = rig.log.stats();
    const auto ps = rig.publisher.stats();
    std::printf(
        "rate x%-3d data %.0f s: cpu %.3f s (%.2f %% of one core per data second), wall %.3f s\n",
        rate_x,
        seconds,
        cpu,
        100.0 * cpu / seconds,
        wall);
    std::printf(
        "  novatel frames %lld/%lld, pings %lld/%zu, published %lld, logged %lld, log drops %lld, "
        "lcm drops %lld, lcm failures %lld -> %s\n",
        static_cast<long long>(nc.frames),
        static_cast<long long>(s.novatel_frames),
        static_cast<long long>(mc.FrameCount("83P")),
        s.pings.size(),
        static_cast<long long>(nc.published + mc.published),
        static_cast<long long>(ls.events_written),
        static_cast<long long>(ls.dropped()),
        static_cast<long long>(ps.queue_drops),
        static_cast<long long>(ps.publish_failures),
        (nc.frames == s.novatel_frames &&
         mc.FrameCount("83P") == static_cast<std::int64_t>(s.pings.size()) && ls.dropped() == 0 &&
         ls.events_written == nc.published + mc.published)
            ? "NO LOSS"
            : "LOSS");
}

void Latency(const std::string& dir) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const Stream s = Make(1.0, 1);
    Rig rig(dir);
    std::vector<double> lat_us;
    std::size_t p = 0;
    for (std::size_t i = 0; i < s.novatel.size(); ++i) {
        const bool with_ping =
            p < s.pings.size() && s.pings[p].utime_host <= s.novatel[i].utime_host;
        const auto t0 = std::chrono::steady_clock::now();
        rig.nov.Process(s.novatel[i]);
        if (with_ping) rig.mb.Process(s.pings[p++]);
        const std::int64_t target = rig.nov.counters().published + rig.mb.counters().published;
        while (rig.log.stats().events_written < target) std::this_thread::yield();
        lat_us.push_back(
            std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0)
                .count());
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    std::sort(lat_us.begin(), lat_us.end());
    std::printf(
        "receive-to-logged latency over %zu chunks: p50 %.0f us, p99 %.0f us, max %.0f us\n",
        lat_us.size(),
        lat_us[lat_us.size() / 2],
        lat_us[lat_us.size() * 99 / 100],
        lat_us.back());
}

}  // namespace

int main(int argc, char** argv) {
    const std::string base =
        (argc > 1 ? std::string(argv[1]) : std::string("/tmp")) + "/pitmap-bench-acqd";
    Throughput(base + "/x1", 1, 30.0);
    Throughput(base + "/x10", 10, 10.0);
    Latency(base + "/lat");
    std::filesystem::remove_all(base);
    return 0;
}
