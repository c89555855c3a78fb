// SPDX-License-Identifier: MIT
// Test helpers for the daemon: a scripted ByteSource, an LCM log reader, a free loopback UDP
// port and a test 83P ping.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>
#include <lcm/lcm-cpp.hpp>

#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "common/protocol/deltat/record83p.hpp"
#include "firmware_host/io/byte_source.hpp"
#include "tests/support/work_dir.hpp"

namespace pitmap::acq::testing {

// A ByteSource that replays a script: chunks of bytes, timeouts, disconnects (the next read
// fails and the following one "reopens", bumping generation()), end of stream. Writes are
// recorded; `on_write` may queue an answer.
class FakeSource final : public ByteSource {
public:
    struct Step {
        enum class Kind { kData, kTimeout, kDisconnect, kEnd } kind = Kind::kData;
        std::vector<std::byte> data;
        std::int64_t utime_host = 0;
        std::int64_t utime_kernel = 0;  // 0 = no kernel receive time
    };

    explicit FakeSource(Transport transport = Transport::kSerial) : transport_(transport) {}

    void PushData(const std::vector<std::uint8_t>& bytes,
                  std::int64_t utime_host,
                  std::int64_t utime_kernel = 0) {
        Step s;
        s.data.resize(bytes.size());
        std::memcpy(s.data.data(), bytes.data(), bytes.size());
        s.utime_host = utime_host;
        s.utime_kernel = utime_kernel;
        steps_.push_back(std::move(s));
    }
    void PushTimeout() { steps_.push_back(Step{Step::Kind::kTimeout, {}, 0, 0}); }
    void PushDisconnect() { steps_.push_back(Step{Step::Kind::kDisconnect, {}, 0, 0}); }
    void PushEnd() { steps_.push_back(Step{Step::Kind::kEnd, {}, 0, 0}); }
    // Puts an answer at the front of the script (the receiver answering a command).
    void PushFrontData(const std::string& text, std::int64_t utime_host) {
        Step s;
        for (char c : text) s.data.push_back(static_cast<std::byte>(c));
        s.utime_host = utime_host;
        steps_.push_front(std::move(s));
    }

    Status Open() override {
        NoteOpened();
        return Ok{};
    }
    Expected<ReadOutcome> Read(Chunk& chunk, int /*timeout_ms*/) override {
        if (state() == SourceState::kDisconnected) {
            NoteOpened();  // the "device" is back
        }
        if (steps_.empty()) return ReadOutcome::kTimeout;
        Step s = std::move(steps_.front());
        steps_.pop_front();
        switch (s.kind) {
            case Step::Kind::kData:
                chunk.data = std::move(s.data);
                chunk.utime_host = s.utime_host;
                chunk.utime_kernel = s.utime_kernel;
                chunk.peer = "fake";
                chunk.truncated = false;
                return ReadOutcome::kData;
            case Step::Kind::kTimeout:
                return ReadOutcome::kTimeout;
            case Step::Kind::kDisconnect:
                set_state(SourceState::kDisconnected);
                return Fail("fake device unplugged");
            case Step::Kind::kEnd:
                set_state(SourceState::kFinished);
                return ReadOutcome::kEndOfStream;
        }
        return ReadOutcome::kTimeout;
    }
    Status Write(std::span<const std::byte> bytes, int /*timeout_ms*/) override {
        std::string text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
        writes.push_back(text);
        if (on_write) on_write(text);
        return Ok{};
    }
    void Close() override { set_state(SourceState::kClosed); }
    Transport transport() const override { return transport_; }
    std::string description() const override { return "fake"; }

    std::vector<std::string> writes;
    std::function<void(const std::string&)> on_write;
    bool empty() const { return steps_.empty(); }

private:
    Transport transport_;
    std::deque<Step> steps_;
};

struct LogEvent {
    std::string channel;
    std::int64_t timestamp = 0;
    std::vector<std::uint8_t> data;
};

// Every event of every *.lcmlog file in `dir`, files in name order.
inline std::vector<LogEvent> ReadLogDir(const std::string& dir) {
    std::vector<std::string> files;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
        if (e.path().extension() == ".lcmlog") files.push_back(e.path().string());
    }
    std::sort(files.begin(), files.end());
    std::vector<LogEvent> out;
    for (const auto& f : files) {
        lcm::LogFile log(f, "r");
        if (!log.good()) continue;
        while (const lcm::LogEvent* ev = log.readNextEvent()) {
            const auto* p = static_cast<const std::uint8_t*>(ev->data);
            out.push_back(LogEvent{
                ev->channel, ev->timestamp, std::vector<std::uint8_t>(p, p + ev->datalen)});
        }
    }
    return out;
}

template <typename T>
T DecodeAs(const std::vector<std::uint8_t>& data) {
    T t;
    const int n = t.decode(data.data(), 0, static_cast<int>(data.size()));
    if (n < 0) ADD_FAILURE() << "undecodable " << T::getTypeName();
    return t;
}

inline std::vector<std::uint8_t> ReadBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {});
}

// TempDir()/NAME, emptied and created; removed after the test program if all passed.
inline std::string FreshDir(const std::string& name) {
    return pitmap::test::MakeWorkDir(::testing::TempDir() + "/" + name).string();
}

// A UDP socket bound to a free port on 127.0.0.1, closed at the end of the scope.
struct BoundUdp {
    int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    int port = 0;
    BoundUdp() {
        sockaddr_in a{};
        a.sin_family = AF_INET;
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a));
        socklen_t len = sizeof(a);
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
        port = ntohs(a.sin_port);
    }
    ~BoundUdp() { ::close(fd); }
    BoundUdp(const BoundUdp&) = delete;
    BoundUdp& operator=(const BoundUdp&) = delete;
};

// A UDP port on 127.0.0.1 that was free a moment ago.
inline int FreeUdpPort() {
    return BoundUdp().port;
}

// Ping `n` as the topside program sends it: 83P v1.10, 480 beams, header time and ranges from
// `n`, intensities on request.
inline std::vector<std::uint8_t> TestPing83P(std::uint32_t n, bool intensities = false) {
    protocol::deltat::Ping83P p;
    p.format_version = protocol::deltat::kVersion110;
    protocol::deltat::SetHeaderTime(p, 1'700'000'000'000'000 + n * 100'000LL);
    p.sector_size_deg = 120;
    p.angle_increment_cdeg = 25;
    p.start_angle_cdeg = -6000;
    p.range_resolution_mm = 10;
    p.ping_number = n;
    p.range_counts.assign(480, static_cast<std::uint16_t>(100 + n % 1000));
    if (intensities) {
        p.intensity_included = true;
        p.intensities.assign(480, static_cast<std::uint16_t>(n % 200));
    }
    return protocol::deltat::EncodeRecord83P(p);
}

}  // namespace pitmap::acq::testing
