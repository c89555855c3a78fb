// SPDX-License-Identifier: MIT
// Ping GPS-time accuracy of pitmap-acqd's data path against injected truth, in real time.
//
// The host clock is the reference of the truth: GPS(h) = GpsFromUnix(h) + kHostBehindGpsUs.
//   * NovAtel (100 Hz INSPVAS, 200 Hz RAWIMUSX, 1 Hz TIMEB, 10 ms serial-like chunks): each
//     message carries GPS(h_valid) and arrives at h = h_valid + d, d uniform 0..1.5 ms; the
//     chunks go through a real SensorChannel (Process() on the feeder thread) into the
//     TimeKeeper's host model.
//   * Delta T 83P v1.10: ping i has its header instant at host time h_i (the ping period
//     plus 0..999 us, so instants fall anywhere within the millisecond); its header clock
//     reads Topside(h_i) = h_i + offset + 40 ppm drift (milliseconds, truncated by the
//     encoder); transmit is ping_latency (2 ms) later, the datagram leaves the topside
//     data_latency (12 ms) after h_i and then suffers a random transport delay 0..20 ms
//     (uniform, or exponential with a 4 ms mean cut at 20 ms) before it is sent over loopback
//     UDP to a real UdpSource + SensorChannel reader thread (kernel receive timestamps).
//   * Truth of ping i: GPS(h_i + ping_latency). Error = published utime_gps - truth.
// Also measured over the whole run (>10 000 NovAtel chunks at the default length), at the
// nominal rates: process CPU (an upper bound: it includes generating and sending the test
// traffic) and receive-to-logged latency (the chunk's utime_host to the LogWriter having
// written all events published so far), with a real LcmPublisher (log only) and LogWriter.
//
// Usage: pitmap-bench-ping_time [seconds per distribution, default 60] [ping Hz, default 10]
//                               [output directory, default /tmp]
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "common/gps_time.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/novatel/encoder.hpp"
#include "firmware_host/daemon/log_writer.hpp"
#include "firmware_host/daemon/publisher.hpp"
#include "firmware_host/daemon/sensor_channel.hpp"
#include "firmware_host/io/udp_source.hpp"
#include "pitmap/multibeam_ping_t.hpp"

namespace {

using namespace pitmap;
using namespace pitmap::acq;
namespace nv = protocol::novatel;
namespace dt = protocol::deltat;

constexpr std::int64_t kHostBehindGpsUs = 250'000;     // host clock error against UTC
constexpr std::int64_t kTopsideOffsetUs = -3'700'000;  // topside clock error at the start
constexpr double kTopsideDriftPpm = 40.0;              // topside clock rate error
constexpr std::int32_t kPingLatencyUs = 2'000;         // header instant -> transmit
constexpr std::int32_t kDataLatencyUs = 12'000;        // header instant -> datagram sent
constexpr std::int64_t kMaxTransportDelayUs = 20'000;
constexpr double kExpMeanUs = 4'000.0;
constexpr double kWarmupS = 15.0;  // the sonar slope is fitted after 10 s of span

std::int64_t Gps(std::int64_t host) {
    return GpsFromUnix(host) + kHostBehindGpsUs;
}

double CpuSeconds() {
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    return static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
           static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-6;
}

void SleepUntilHost(std::int64_t host_us) {
    const std::int64_t now = HostNowUtime();
    if (host_us > now) std::this_thread::sleep_for(std::chrono::microseconds(host_us - now));
}

// A NovAtel source that is never read: the feeder thread calls Process() itself.
class PushedSource final : public ByteSource {
public:
    Status Open() override {
        NoteOpened();
        return Ok{};
    }
    Expected<ReadOutcome> Read(Chunk&, int) override { return ReadOutcome::kEndOfStream; }
    Status Write(std::span<const std::byte>, int) override { return Ok{}; }
    void Close() override {}
    Transport transport() const override { return Transport::kSerial; }
    std::string description() const override { return "bench feeder"; }
};

// Forwards to the real publisher and keeps (utime_gps, source) of every ping by number.
class TeePublisher final : public Publisher {
public:
    explicit TeePublisher(Publisher& next) : next_(next) {}
    bool Publish(std::string_view channel,
                 std::int64_t utime,
                 std::vector<std::uint8_t> data) override {
        if (channel.starts_with(lcmlog::kChannelMultibeamPing)) {
            pitmap::multibeam_ping_t p;
            if (p.decode(data.data(), 0, static_cast<int>(data.size())) >= 0) {
                std::lock_guard<std::mutex> lock(mu_);
                pings_[p.ping_number] = {p.utime_gps, p.gps_time_source};
            }
        }
        return next_.Publish(channel, utime, std::move(data));
    }
    std::map<std::int64_t, std::pair<std::int64_t, std::int8_t>> pings() const {
        std::lock_guard<std::mutex> lock(mu_);
        return pings_;
    }

private:
    Publisher& next_;
    mutable std::mutex mu_;
    std::map<std::int64_t, std::pair<std::int64_t, std::int8_t>> pings_;
};

nv::Header ShortHeader(std::uint16_t id, std::int64_t gps_us) {
    nv::Header h;
    h.kind = nv::HeaderKind::kShortBinary;
    h.message_id = id;
    h.gps_week = static_cast<std::uint16_t>(gps_us / kMicrosPerWeek);
    h.gps_ms = static_cast<std::uint32_t>((gps_us % kMicrosPerWeek) / 1000);
    return h;
}

// One 10 ms chunk of NovAtel output whose newest message is valid at GPS time `gps`.
std::vector<std::uint8_t> NovatelChunk(std::int64_t gps, bool with_time) {
    std::vector<std::uint8_t> buf;
    const auto week = static_cast<std::uint32_t>(gps / kMicrosPerWeek);
    for (std::int64_t t : {gps - 5'000, gps}) {
        nv::RawImu m;
        m.header = ShortHeader(nv::msg_id::kRawImuSX, t);
        m.imu_type = 13;
        m.gps_week = week;
        m.gps_seconds = static_cast<double>(t % kMicrosPerWeek) * 1e-6;
        m.accel_counts = {1000, -2000, 300000};
        m.gyro_counts = {10, 20, -30};
        nv::EncodeBinary(m, buf);
    }
    nv::InsPva p;
    p.header = ShortHeader(nv::msg_id::kInsPvaS, gps);
    p.gps_week = week;
    p.gps_seconds = static_cast<double>(gps % kMicrosPerWeek) * 1e-6;
    p.latitude_deg = 41.1;
    p.ins_status = nv::InsStatus::kSolutionGood;
    nv::EncodeBinary(p, buf);
    if (with_time) {
        nv::Time t;
        t.header = ShortHeader(nv::msg_id::kTime, gps);
        t.header.kind = nv::HeaderKind::kLongBinary;
        t.header.time_status = nv::TimeStatus::kFineSteering;
        nv::EncodeBinary(t, buf);
    }
    return buf;
}

std::vector<std::uint8_t> PingRecord(std::uint32_t n, std::int64_t topside_us) {
    dt::Ping83P p;
    p.format_version = dt::kVersion110;
    dt::SetHeaderTime(p, topside_us);
    p.sector_size_deg = 120;
    p.angle_increment_cdeg = 25;
    p.start_angle_cdeg = -6000;
    p.range_resolution_mm = 10;
    p.ping_number = n;
    p.ping_latency_us = kPingLatencyUs;
    p.data_latency_us = kDataLatencyUs;
    p.range_counts.assign(480, static_cast<std::uint16_t>(1000 + n % 100));
    p.intensity_included = true;
    p.intensities.assign(480, 77);
    return dt::EncodeRecord83P(p);
}

double Percentile(std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const auto i = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
    return v[std::min(i, v.size() - 1)];
}

struct Totals {
    std::vector<double> latency_us;
    std::int64_t chunks = 0;
    double cpu_s = 0.0;
    double wall_s = 0.0;
    bool loss = false;
};

enum class Delay { kUniform, kExponential };

void Session(Delay kind, double seconds, double ping_hz, const std::string& dir, Totals& totals) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    LogWriter log(LogWriterConfig{.directory = dir, .prefix = "bench", .min_free_bytes = 0});
    LcmPublisher lcm_pub(LcmPublisherConfig{.lcm_url = ""}, &log);
    if (!log.Start() || !lcm_pub.Start()) {
        std::fprintf(stderr, "cannot start the log writer in %s\n", dir.c_str());
        return;
    }
    TeePublisher publisher(lcm_pub);
    SystemClock clock;
    TimeKeeper time;
    PushedSource nov_src;
    SensorChannelConfig nov_cfg;
    nov_cfg.id = "nov";
    nov_cfg.imu.imu_type = 13;
    nov_cfg.imu.imu_rate_hz = 200.0;
    SensorChannel nov(nov_cfg, nov_src, publisher, clock, time);
    (void)nov_src.Open();
    UdpConfig udp_cfg;
    udp_cfg.bind_address = "127.0.0.1";
    udp_cfg.port = 0;
    udp_cfg.allowed_senders = {"127.0.0.1"};
    UdpSource udp(udp_cfg);
    SensorChannelConfig mb_cfg;
    mb_cfg.id = "mb";
    mb_cfg.protocol = ChannelProtocol::kDeltat83P;
    SensorChannel mb(mb_cfg, udp, publisher, clock, time);
    mb.Start();
    const int port = udp.bound_port();

    const double c0 = CpuSeconds();
    const auto w0 = std::chrono::steady_clock::now();
    std::atomic<bool> stop{false};
    std::int64_t chunks = 0;
    std::vector<double> latency;
    std::thread feeder([&] {
        std::mt19937_64 rng(7);
        std::uniform_int_distribution<std::int64_t> serial_delay(0, 1'500);
        std::int64_t next = HostNowUtime();
        for (std::int64_t k = 0; !stop.load(); ++k) {
            next += 10'000;
            SleepUntilHost(next);
            Chunk c;
            c.utime_host = HostNowUtime();
            const auto bytes = NovatelChunk(Gps(c.utime_host - serial_delay(rng)), k % 100 == 0);
            c.data.resize(bytes.size());
            std::memcpy(c.data.data(), bytes.data(), bytes.size());
            c.peer = "bench";
            nov.Process(c);
            const std::int64_t target = nov.counters().published + mb.counters().published;
            for (int spin = 0; spin < 100'000 && log.stats().events_written < target; ++spin) {
                std::this_thread::yield();
            }
            latency.push_back(static_cast<double>(HostNowUtime() - c.utime_host));
            ++chunks;
        }
    });

    // Warm up the host model (lock needs 20 samples), then the pings.
    std::this_thread::sleep_for(std::chrono::milliseconds(1000));
    const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<std::uint16_t>(port));
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    std::mt19937_64 rng(kind == Delay::kUniform ? 11 : 13);
    std::uniform_int_distribution<std::int64_t> uniform(0, kMaxTransportDelayUs);
    std::exponential_distribution<double> expo(1.0 / kExpMeanUs);
    std::uniform_int_distribution<std::int64_t> off_grid(0, 999);
    const auto num_pings = static_cast<std::uint32_t>(seconds * ping_hz);
    const auto period_us = static_cast<std::int64_t>(1e6 / ping_hz);
    const std::int64_t h0 = HostNowUtime() + 50'000;
    std::vector<std::int64_t> truth(num_pings), header_host(num_pings);
    for (std::uint32_t i = 0; i < num_pings; ++i) {
        // Ping instants off the millisecond grid (as a real ping cycle is), so the header's
        // truncated milliseconds take every fraction.
        const std::int64_t h = h0 + static_cast<std::int64_t>(i) * period_us + off_grid(rng);
        const std::int64_t topside =
            h + kTopsideOffsetUs +
            static_cast<std::int64_t>(kTopsideDriftPpm * 1e-6 * static_cast<double>(h - h0));
        const std::int64_t delay =
            kind == Delay::kUniform ? uniform(rng)
                                    : std::min<std::int64_t>(static_cast<std::int64_t>(expo(rng)),
                                                             kMaxTransportDelayUs);
        truth[i] = Gps(h + kPingLatencyUs);
        header_host[i] = h;
        const auto rec = PingRecord(i, topside);
        SleepUntilHost(h + kDataLatencyUs + delay);
        ::sendto(fd, rec.data(), rec.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof(to));
    }
    ::close(fd);
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    stop = true;
    feeder.join();
    mb.Stop();
    lcm_pub.Drain(10'000);
    log.Flush(10'000);
    const double cpu = CpuSeconds() - c0;
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
    lcm_pub.Stop();
    log.Stop();

    const auto pings = publisher.pings();
    std::vector<double> err_all, err_steady;
    int header_model = 0, receive = 0, none = 0;
    for (std::uint32_t i = 0; i < num_pings; ++i) {
        const auto it = pings.find(i);
        if (it == pings.end()) continue;
        const auto [utime_gps, source] = it->second;
        if (utime_gps == 0) {
            ++none;
            continue;
        }
        header_model += source == pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK;
        receive += source == pitmap::multibeam_ping_t::TIME_SOURCE_RECEIVE;
        const double e = std::abs(static_cast<double>(utime_gps - truth[i]));
        err_all.push_back(e);
        if (static_cast<double>(header_host[i] - h0) >= kWarmupS * 1e6) err_steady.push_back(e);
    }
    const auto ls = log.stats();
    const auto nc = nov.counters();
    const auto mc = mb.counters();
    const bool loss = mc.FrameCount("83P") != num_pings || ls.dropped() != 0 ||
                      nc.queue_drops != 0 || mc.queue_drops != 0 || nc.crc_failures != 0;
    std::printf(
        "%s transport delays 0-20 ms: %u pings sent, %zu published (%d header model, "
        "%d receive fallback, %d without time)\n",
        kind == Delay::kUniform ? "uniform" : "exponential (mean 4 ms, cut at 20 ms)",
        num_pings,
        pings.size(),
        header_model,
        receive,
        none);
    std::printf("  |utime_gps - truth| all:            p50 %7.0f us  p99 %7.0f us  max %7.0f us\n",
                Percentile(err_all, 0.5),
                Percentile(err_all, 0.99),
                err_all.empty() ? 0.0 : *std::max_element(err_all.begin(), err_all.end()));
    std::printf(
        "  |utime_gps - truth| after %2.0f s:     p50 %7.0f us  p99 %7.0f us  max %7.0f us"
        " (%zu pings) -> %s\n",
        kWarmupS,
        Percentile(err_steady, 0.5),
        Percentile(err_steady, 0.99),
        err_steady.empty() ? 0.0 : *std::max_element(err_steady.begin(), err_steady.end()),
        err_steady.size(),
        Percentile(err_steady, 0.99) < 2000.0 ? "p99 < 2 ms" : "MISSED");
    std::printf("  novatel chunks %lld, frames %lld, log events %lld, drops %lld -> %s\n",
                static_cast<long long>(chunks),
                static_cast<long long>(nc.frames),
                static_cast<long long>(ls.events_written),
                static_cast<long long>(ls.dropped()),
                loss ? "LOSS" : "NO LOSS");
    totals.latency_us.insert(totals.latency_us.end(), latency.begin(), latency.end());
    totals.chunks += chunks;
    totals.cpu_s += cpu;
    totals.wall_s += wall;
    totals.loss = totals.loss || loss;
}

}  // namespace

int main(int argc, char** argv) {
    const double seconds = argc > 1 ? std::atof(argv[1]) : 60.0;
    const double ping_hz = argc > 2 ? std::atof(argv[2]) : 10.0;
    const std::string base =
        (argc > 3 ? std::string(argv[3]) : std::string("/tmp")) + "/pitmap-bench-ping-time";
    if (seconds <= 0.0 || ping_hz <= 0.0 || ping_hz > 30.0) {
        std::fprintf(stderr, "usage: pitmap-bench-ping_time [seconds > 0] [ping Hz 0..30] [dir]\n");
        return 2;
    }
    Totals totals;
    Session(Delay::kUniform, seconds, ping_hz, base + "/uniform", totals);
    Session(Delay::kExponential, seconds, ping_hz, base + "/exponential", totals);
    std::printf(
        "nominal rates (INSPVAS 100 Hz, RAWIMUSX 200 Hz, TIMEB 1 Hz, pings %.0f Hz), "
        "%.0f s wall: process CPU %.2f %% of one core (upper bound: includes the "
        "traffic generators)\n",
        ping_hz,
        totals.wall_s,
        100.0 * totals.cpu_s / totals.wall_s);
    std::printf(
        "receive-to-logged latency over %lld chunks: p50 %.0f us, p99 %.0f us, max %.0f us"
        " -> %s\n",
        static_cast<long long>(totals.chunks),
        Percentile(totals.latency_us, 0.5),
        Percentile(totals.latency_us, 0.99),
        totals.latency_us.empty()
            ? 0.0
            : *std::max_element(totals.latency_us.begin(), totals.latency_us.end()),
        totals.loss ? "with LOSS" : "no loss");
    std::filesystem::remove_all(base);
    return totals.loss ? 1 : 0;
}
