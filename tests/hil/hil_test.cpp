// SPDX-License-Identifier: MIT
// HIL: `pitmap-sim hil` runs a short demo survey in real time behind a pseudo-terminal (COM1,
// paced at 460800 baud), a TCP ICOM port and UDP 83P datagrams, with injected faults, while
// the real pitmap-acqd (a child process) logs it. Then the daemon's LCM log is held against the
// emulators' manifest:
//   - each NovAtel source's raw chunks, in sequence order, reassemble to exactly the bytes the
//     emulator put on that wire (frames, corrupted frames, garbage, command responses), so every
//     frame is there exactly once;
//   - every 83P datagram is one raw chunk, once; every ping is published once, with a GPS
//     time within 2 ms (p99) of the true transmit time;
//   - the daemon's last DAEMON_STATUS / STATUS_<ID> counters equal the injected faults (CRC
//     failures, reconnects after the pty unplug and the TCP drop) and the EC frames the
//     topside received.
// Loopback only: free ports on 127.0.0.1, LCM memq:// (nothing leaves the daemon; the log is
// the output). Skips when pitmap-acqd or pitmap-sim is not built, or the machine has no ptys.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "common/gps_time.hpp"
#include "common/protocol/novatel/framer.hpp"
#include "common/protocol/novatel/messages.hpp"
#include "pitmap/clock_sync_t.hpp"
#include "pitmap/daemon_status_t.hpp"
#include "pitmap/multibeam_ping_t.hpp"
#include "pitmap/raw_bytes_t.hpp"
#include "processor/io/ingest.hpp"
#include "tests/support/process.hpp"
#include "tools/sim/hil/manifest.hpp"
#include "tools/sim/hil/novatel_emulator.hpp"
#include "tools/sim/hil/realtime.hpp"
#include "tools/sim/nav_errors.hpp"
#include "tools/sim/trajectory.hpp"

namespace fs = std::filesystem;
using nlohmann::json;
using pitmap::test::FreePort;
using pitmap::test::ReadText;

namespace {

constexpr double kDurationS = 40.0;
// Jitter: up to 1 ms on loopback, as on the direct Ethernet link from the topside PC. The daemon
// fits its sonar clock from below, so jitter shows in the first pings only, before the envelope
// has seen a fast datagram.
constexpr const char* kFaults = "garbage=3,crc=3,unplug=1,tcp-drop=1,jitter-ms=1";

struct Event {
    std::string channel;
    std::vector<std::uint8_t> data;
};

std::vector<Event> ReadLog(const fs::path& dir) {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(dir)) {
        if (e.path().extension() == ".lcmlog") files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());  // segment names sort in time order
    std::vector<Event> events;
    for (const auto& f : files) {
        lcm::LogFile log(f.string(), "r");
        if (!log.good()) continue;
        for (int i = 0; i < 50'000'000; ++i) {
            const lcm::LogEvent* ev = log.readNextEvent();
            if (ev == nullptr) break;
            const auto* d = static_cast<const std::uint8_t*>(ev->data);
            events.push_back({ev->channel, std::vector<std::uint8_t>(d, d + ev->datalen)});
        }
    }
    return events;
}

template <typename T>
bool Decode(const Event& e, T& out) {
    return out.decode(e.data.data(), 0, static_cast<int>(e.data.size())) >= 0;
}

double Percentile(std::vector<double> v, double q) {
    if (v.empty()) return NAN;
    std::sort(v.begin(), v.end());
    const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
    return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

std::int64_t FrameKindCount(const pitmap::channel_status_t& s, const std::string& kind) {
    for (int i = 0; i < s.num_frame_kinds; ++i) {
        if (s.frame_kind[static_cast<std::size_t>(i)] == kind) {
            return s.frame_count[static_cast<std::size_t>(i)];
        }
    }
    return 0;
}

std::int64_t SkippedBytes(const pitmap::channel_status_t& s, const std::string& reason) {
    for (int i = 0; i < s.num_skip_reasons; ++i) {
        if (s.skip_reason[static_cast<std::size_t>(i)] == reason) {
            return s.skipped_bytes[static_cast<std::size_t>(i)];
        }
    }
    return 0;
}

}  // namespace

TEST(Hil, DaemonLogMatchesTheEmulatorsManifest) {
    const fs::path bin = PITMAP_BIN_DIR;
    const fs::path acqd = bin / "pitmap-acqd", sim = bin / "pitmap-sim";
    if (!fs::exists(acqd)) GTEST_SKIP() << "pitmap-acqd is not built: HIL test skipped";
    if (!fs::exists(sim)) GTEST_SKIP() << "pitmap-sim is not built: HIL test skipped";
    const fs::path dir = pitmap::test::FreshDir("pitmap_hil");
    const int tcp_port = FreePort(SOCK_STREAM), udp_port = FreePort(SOCK_DGRAM);
    ASSERT_GT(tcp_port, 0);
    ASSERT_GT(udp_port, 0);
    const fs::path out = dir / "run";
    const std::vector<std::string> args = pitmap::test::HilRigArgs(
        bin, kDurationS, out, dir / "com1", tcp_port, udp_port, {"--faults", kFaults});
    // Stopped with SIGTERM and 5 s to finish when it overruns.
    const int rc = pitmap::test::Wait(
        pitmap::test::Spawn(args, (dir / "sim.out").string()), kDurationS + 120, 5);
    const std::string sim_out = ReadText(dir / "sim.out");
    if (rc != 0 && sim_out.find("no pseudo-terminal") != std::string::npos) {
        GTEST_SKIP() << "no pty support on this machine: " << sim_out;
    }
    ASSERT_EQ(rc, 0) << sim_out << "\n--- acqd.out:\n" << ReadText(out / "acqd.out");

    // The manifest: byte items per source in wire order, datagrams, faults, EC frames.
    std::map<std::string, std::vector<json>> stream_items;
    std::vector<json> datagrams;
    std::map<std::string, int> faults;
    std::map<std::string, int> commands_ok;
    int ec_received = 0;
    {
        std::ifstream in(out / "truth" / "hil_manifest.jsonl");
        ASSERT_TRUE(in) << "no manifest";
        std::string line;
        while (std::getline(in, line)) {
            json j = json::parse(line);
            const std::string kind = j["kind"], source = j["source"];
            if (kind == "frame" || kind == "corrupt_frame" || kind == "garbage" ||
                kind == "response") {
                stream_items[source].push_back(j);
            } else if (kind == "datagram") {
                datagrams.push_back(j);
            } else if (kind == "fault") {
                faults[j["fault"].get<std::string>()]++;
                if (j["fault"] == "unplug") {
                    EXPECT_EQ(j["unread_bytes"], 0) << "bytes lost at unplug";
                }
            } else if (kind == "ec") {
                ++ec_received;
            } else if (kind == "command" && j["answer"] == "OK") {
                commands_ok[source]++;
            }
        }
    }
    ASSERT_EQ(faults["crc"], 3);
    ASSERT_EQ(faults["garbage"], 3);
    ASSERT_EQ(faults["unplug"], 1);
    ASSERT_EQ(faults["tcp_drop"], 1);

    // The daemon's log.
    const std::vector<Event> events = ReadLog(out / "log");
    ASSERT_FALSE(events.empty()) << "empty log\n" << ReadText(out / "acqd.out");
    std::map<std::string, std::vector<pitmap::raw_bytes_t>> raw;
    std::vector<pitmap::multibeam_ping_t> pings;
    std::vector<pitmap::clock_sync_t> clock_syncs;
    pitmap::daemon_status_t status;
    bool have_status = false;
    std::map<std::string, pitmap::channel_status_t> channel_status;
    for (const Event& e : events) {
        if (e.channel.rfind("RAW_", 0) == 0) {
            pitmap::raw_bytes_t r;
            ASSERT_TRUE(Decode(e, r)) << e.channel;
            raw[r.source].push_back(std::move(r));
        } else if (e.channel.rfind("MULTIBEAM_PING_", 0) == 0) {
            pitmap::multibeam_ping_t p;
            ASSERT_TRUE(Decode(e, p));
            pings.push_back(std::move(p));
        } else if (e.channel == "CLOCK_SYNC") {
            pitmap::clock_sync_t c;
            ASSERT_TRUE(Decode(e, c));
            clock_syncs.push_back(c);
        } else if (e.channel == "DAEMON_STATUS") {
            ASSERT_TRUE(Decode(e, status));
            have_status = true;
        } else if (e.channel.rfind("STATUS_", 0) == 0) {
            pitmap::channel_status_t s;
            ASSERT_TRUE(Decode(e, s));
            channel_status[s.name] = s;
        }
    }
    ASSERT_TRUE(have_status);

    // 1. NovAtel byte streams: reassembled raw chunks == the manifest's items, in order.
    std::map<std::string, std::int64_t> frames_matched;
    for (const char* source : {"novatel_com1", "novatel_icom1"}) {
        auto& chunks = raw[source];
        ASSERT_FALSE(chunks.empty()) << source;
        std::sort(chunks.begin(), chunks.end(), [](const auto& a, const auto& b) {
            return a.seq < b.seq;
        });
        std::vector<std::uint8_t> stream;
        for (std::size_t i = 0; i < chunks.size(); ++i) {
            EXPECT_EQ(chunks[i].seq, chunks.front().seq + static_cast<std::int64_t>(i))
                << source << ": a raw chunk is missing";
            stream.insert(stream.end(), chunks[i].data.begin(), chunks[i].data.end());
        }
        std::size_t pos = 0;
        std::size_t mismatches = 0;
        for (const json& item : stream_items[source]) {
            const std::size_t len = item["len"];
            const std::string kind = item["kind"];
            if (pos + len > stream.size()) {
                ADD_FAILURE() << source << ": the log ends at byte " << stream.size()
                              << " before the " << kind << " at " << pos << " (len " << len << ")";
                mismatches = 1;
                break;
            }
            const std::string h = pitmap::sim::hil::HexU64(
                pitmap::sim::hil::Fnv1a64(std::span<const std::uint8_t>(stream.data() + pos, len)));
            if (h != item["fnv64"].get<std::string>()) {
                // Diagnosis: where the item's bytes are in the log (bytes missing or extra
                // before it), and the log's bytes here.
                std::string where = "not within 4096 bytes of it";
                for (long d = 1; d <= 4096; ++d) {
                    bool found = false;
                    for (const long off :
                         {static_cast<long>(pos) + d, static_cast<long>(pos) - d}) {
                        if (off < 0 || static_cast<std::size_t>(off) + len > stream.size())
                            continue;
                        const std::string hd = pitmap::sim::hil::HexU64(pitmap::sim::hil::Fnv1a64(
                            std::span<const std::uint8_t>(stream.data() + off, len)));
                        if (hd == item["fnv64"].get<std::string>()) {
                            where = "found at byte " + std::to_string(off) + " (" +
                                    std::to_string(off - static_cast<long>(pos)) + " bytes away)";
                            found = true;
                            break;
                        }
                    }
                    if (found) break;
                }
                std::string hex;
                for (std::size_t i = pos; i < std::min(stream.size(), pos + 32); ++i) {
                    char b[4];
                    std::snprintf(b, sizeof b, "%02x", stream[i]);
                    hex += b;
                }
                ADD_FAILURE() << source << ": " << kind << " (len " << len << ") at byte " << pos
                              << " (t " << item["t_s"] << " s) differs from what the emulator "
                              << "sent; its bytes are " << where << "; the log there: " << hex;
                mismatches = 1;
                break;
            }
            if (kind == "frame" || kind == "corrupt_frame") ++frames_matched[source];
            pos += len;
        }
        if (mismatches == 0) {
            EXPECT_EQ(pos, stream.size()) << source << ": bytes in the log the emulator never sent";
        }
    }

    // 2. Datagrams: each one raw chunk, exactly once.
    std::map<std::string, int> chunk_hashes;
    for (const auto& r : raw["deltat_udp"]) {
        chunk_hashes[pitmap::sim::hil::HexU64(pitmap::sim::hil::Fnv1a64(r.data))]++;
    }
    int datagrams_once = 0;
    for (const json& d : datagrams) {
        const int n = chunk_hashes[d["fnv64"].get<std::string>()];
        EXPECT_EQ(n, 1) << "ping " << d["ping"] << " logged " << n << " times";
        datagrams_once += n == 1 ? 1 : 0;
    }
    EXPECT_EQ(raw["deltat_udp"].size(), datagrams.size());

    // 3. Pings: once each, GPS time vs the true transmit time.
    std::map<std::int64_t, std::vector<const pitmap::multibeam_ping_t*>> by_number;
    for (const auto& p : pings) by_number[p.ping_number].push_back(&p);
    // The sonar clock model reports CONVERGING ("times usable with a larger error") until its
    // window is long enough; the 2 ms criterion applies from its first LOCKED status on.
    std::int64_t sonar_locked_utime = std::numeric_limits<std::int64_t>::max();
    for (const auto& c : clock_syncs) {
        if (c.source == pitmap::clock_sync_t::SOURCE_SONAR_HEADER &&
            c.state == pitmap::clock_sync_t::STATE_LOCKED) {
            sonar_locked_utime = std::min(sonar_locked_utime, c.utime);
        }
    }
    std::vector<double> errors_ms, settled_errors_ms;  // all; once the sonar clock is LOCKED
    double signed_sum_ms = 0;
    int unstamped = 0;
    // Per-ping errors beside the run, kept when the test fails.
    std::ofstream error_csv(dir / "ping_errors.csv");
    error_csv << "ping,t_s,error_ms,stddev_ms,time_source,emulator_late_ms\n";
    // Every ping within 5 ms of its true time. Before the sonar clock has a floor (CONVERGING)
    // a stamp holds the delay of the few datagrams the model has seen; the part of it that is
    // the emulator's own thread sending late under load (the manifest's "late_us", beyond the
    // designed jitter) is this machine's scheduling, not the daemon's error, and is added to
    // the bound until the model locks. Once LOCKED the envelope takes the floor: 5 ms flat.
    constexpr double kMaxErrorMs = 5.0;
    double late_so_far_ms = 0;
    std::vector<std::string> over_bound;
    for (const json& d : datagrams) {
        late_so_far_ms = std::max(late_so_far_ms, d.value("late_us", 0.0) * 1e-3);
        const auto& found = by_number[d["ping"].get<std::int64_t>()];
        ASSERT_EQ(found.size(), 1u) << "ping " << d["ping"];
        if (found[0]->utime_gps == 0) {
            ++unstamped;
            continue;
        }
        const std::int64_t truth = d["utime_gps_transmit"];
        const double e_ms = static_cast<double>(found[0]->utime_gps - truth) * 1e-3;
        error_csv << d["ping"] << "," << d["t_s"] << "," << e_ms << ","
                  << found[0]->gps_time_stddev_s * 1e3 << ","
                  << static_cast<int>(found[0]->gps_time_source) << "," << late_so_far_ms << "\n";
        errors_ms.push_back(std::abs(e_ms));
        const bool locked = found[0]->utime >= sonar_locked_utime;
        if (locked) settled_errors_ms.push_back(std::abs(e_ms));
        const double bound_ms = kMaxErrorMs + (locked ? 0.0 : late_so_far_ms);
        if (std::abs(e_ms) > bound_ms && over_bound.size() < 8) {
            over_bound.push_back("ping " + d["ping"].dump() + ": " + std::to_string(e_ms) +
                                 " ms against " + std::to_string(bound_ms) + " ms" +
                                 (locked ? "" : " (before LOCKED)"));
        }
        signed_sum_ms += e_ms;
    }
    EXPECT_EQ(pings.size(), datagrams.size());
    const double p50 = Percentile(errors_ms, 0.50), p99 = Percentile(errors_ms, 0.99);
    const double p99_locked = Percentile(settled_errors_ms, 0.99);
    const double max_err =
        errors_ms.empty() ? NAN : *std::max_element(errors_ms.begin(), errors_ms.end());
    EXPECT_LE(unstamped, static_cast<int>(datagrams.size() / 10))
        << "pings without a GPS time (clock model not locked)";
    std::string worst;
    {
        std::vector<std::pair<double, std::int64_t>> w;
        for (const json& d : datagrams) {
            const auto& found = by_number[d["ping"].get<std::int64_t>()];
            if (found.size() != 1 || found[0]->utime_gps == 0) continue;
            const std::int64_t truth = d["utime_gps_transmit"];
            w.emplace_back(static_cast<double>(found[0]->utime_gps - truth) * 1e-3,
                           d["ping"].get<std::int64_t>());
        }
        std::sort(w.begin(), w.end(), [](const auto& a, const auto& b) {
            return std::abs(a.first) > std::abs(b.first);
        });
        for (std::size_t i = 0; i < std::min<std::size_t>(8, w.size()); ++i) {
            worst +=
                " ping " + std::to_string(w[i].second) + ": " + std::to_string(w[i].first) + " ms;";
        }
    }
    EXPECT_GE(settled_errors_ms.size(), datagrams.size() / 2) << "sonar clock locked late";
    EXPECT_LE(p99_locked, 2.0) << "ping GPS time error p99 (sonar clock LOCKED), ms";
    EXPECT_TRUE(over_bound.empty())
        << "ping GPS time error over its bound (first 8): " << testing::PrintToString(over_bound)
        << "; worst:" << worst << "; emulator late up to " << late_so_far_ms << " ms";

    // The host clock model against the truth: in this rig GPS - Unix is exactly the leap
    // seconds, so the model's offset at its reference point shows its error directly.
    std::vector<double> host_errors_ms;
    for (const auto& c : clock_syncs) {
        if (c.source != pitmap::clock_sync_t::SOURCE_HOST_FROM_NOVATEL || c.state == 0) continue;
        // GPS = Unix - 315 964 800 s (1980-01-06) + leap seconds.
        const std::int64_t truth_offset_us =
            (std::int64_t{c.leap_seconds} - 315'964'800LL) * 1'000'000;
        const double e = static_cast<double>(c.offset_us - truth_offset_us);
        host_errors_ms.push_back(std::abs(e) * 1e-3);
        error_csv << "# host clock at " << c.utime << ": state " << static_cast<int>(c.state)
                  << ", error " << e * 1e-3 << " ms\n";
    }
    for (const auto& c : clock_syncs) {
        if (c.source != pitmap::clock_sync_t::SOURCE_SONAR_HEADER) continue;
        error_csv << "# sonar clock at " << c.utime << ": state " << static_cast<int>(c.state)
                  << ", drift " << c.drift_ppm << " ppm, samples " << c.num_samples << "\n";
    }
    // Reported, not judged: the pings carry the criterion; the envelope's floor includes the
    // emulator's pacing granularity (0.5 ms wake-ups) and this machine's scheduling.
    std::printf("HIL host clock model error (%zu CLOCK_SYNC): p50 %.3f ms, max %.3f ms\n",
                host_errors_ms.size(),
                Percentile(host_errors_ms, 0.5),
                Percentile(host_errors_ms, 1.0));

    // 4. Counters: the daemon's last status against the injected faults.
    std::map<std::string, pitmap::channel_status_t> last;
    for (const auto& c : status.channels) last[c.name] = c;
    ASSERT_EQ(last.count("novatel_com1"), 1u);
    ASSERT_EQ(last.count("novatel_icom1"), 1u);
    ASSERT_EQ(last.count("deltat_udp"), 1u);
    const auto& com = last["novatel_com1"];
    const auto& icom = last["novatel_icom1"];
    const auto& udp = last["deltat_udp"];
    EXPECT_EQ(com.crc_failures, faults["crc"]);
    EXPECT_EQ(com.reconnects, faults["unplug"]);
    EXPECT_EQ(icom.reconnects, faults["tcp_drop"]);
    EXPECT_EQ(icom.crc_failures, 0);
    EXPECT_EQ(com.frames,
              frames_matched["novatel_com1"] - faults["crc"] + commands_ok["novatel_com1"] * 2)
        << "frames the daemon framed on COM1 (logs, <OK, prompts)";
    EXPECT_EQ(FrameKindCount(com, "CMD_OK"), commands_ok["novatel_com1"]);
    EXPECT_EQ(FrameKindCount(icom, "CMD_OK"), commands_ok["novatel_icom1"]);
    EXPECT_EQ(FrameKindCount(udp, "EC_SENT"), ec_received);
    EXPECT_EQ(FrameKindCount(udp, "83P"), static_cast<std::int64_t>(datagrams.size()));
    // The emulated topside is the allowed sender (127.0.0.1); the socket kept up.
    EXPECT_EQ(udp.foreign_datagrams, 0);
    EXPECT_EQ(udp.kernel_drops, 0);
    EXPECT_GE(SkippedBytes(com, "garbage"), 16 * faults["garbage"]);
    for (const auto& [name, s] : channel_status) {
        EXPECT_EQ(s.crc_failures, last[name].crc_failures) << "STATUS_ vs DAEMON_STATUS " << name;
        EXPECT_EQ(s.reconnects, last[name].reconnects) << name;
    }
    EXPECT_EQ(status.log_events_dropped, 0);

    // 5. Issue 16: the shore re-decoding RAW_ (raw source) gives every ping the time the
    // running daemon published on MULTIBEAM_PING_ (its reader threads racing for the clock).
    std::vector<std::string> log_files;
    for (const auto& e : fs::directory_iterator(out / "log")) {
        if (e.path().extension() == ".lcmlog") log_files.push_back(e.path().string());
    }
    std::sort(log_files.begin(), log_files.end());
    pitmap::proc::io::IngestConfig ingest;
    ingest.source = pitmap::proc::io::IngestSource::kDecoded;
    const auto from_decoded = pitmap::proc::io::IngestLcmLogs(log_files, ingest);
    ingest.source = pitmap::proc::io::IngestSource::kRaw;
    const auto from_raw = pitmap::proc::io::IngestLcmLogs(log_files, ingest);
    ASSERT_TRUE(from_decoded.ok()) << from_decoded.error().message;
    ASSERT_TRUE(from_raw.ok()) << from_raw.error().message;
    const auto& dec = from_decoded->pings.pings;
    const auto& red = from_raw->pings.pings;
    EXPECT_GT(dec.size(), datagrams.size() / 2);
    ASSERT_EQ(red.size(), dec.size());
    std::int64_t redecode_max_us = 0;
    for (std::size_t k = 0; k < dec.size(); ++k) {
        EXPECT_EQ(red[k].ping_number, dec[k].ping_number) << "at " << k;
        redecode_max_us = std::max(redecode_max_us, std::abs(red[k].utime_gps - dec[k].utime_gps));
    }
    EXPECT_EQ(redecode_max_us, 0);
    std::printf("HIL re-decoded RAW_ vs MULTIBEAM_PING_: %zu pings, max difference %lld us\n",
                dec.size(),
                static_cast<long long>(redecode_max_us));

    std::printf(
        "HIL measured: COM1 %lld frames, ICOM1 %lld frames, %zu datagrams (%d logged once), "
        "%zu pings stamped (%d unstamped); ping GPS time error p50 %.3f ms, p99 %.3f ms, "
        "max %.3f ms, mean signed %+.3f ms; %zu pings after the sonar clock LOCKED: p50 %.3f ms, "
        "p99 %.3f ms; faults injected: %d CRC, %d garbage, %d unplug, %d TCP drop; daemon "
        "counted: COM1 crc %lld, reconnects %lld, ICOM1 reconnects %lld, garbage bytes "
        "%lld; EC frames %d\n",
        static_cast<long long>(frames_matched["novatel_com1"]),
        static_cast<long long>(frames_matched["novatel_icom1"]),
        datagrams.size(),
        datagrams_once,
        errors_ms.size(),
        unstamped,
        p50,
        p99,
        max_err,
        errors_ms.empty() ? NAN : signed_sum_ms / static_cast<double>(errors_ms.size()),
        settled_errors_ms.size(),
        Percentile(settled_errors_ms, 0.5),
        p99_locked,
        faults["crc"],
        faults["garbage"],
        faults["unplug"],
        faults["tcp_drop"],
        static_cast<long long>(com.crc_failures),
        static_cast<long long>(com.reconnects),
        static_cast<long long>(icom.reconnects),
        static_cast<long long>(SkippedBytes(com, "garbage")),
        ec_received);
    RecordProperty("ping_error_p50_ms", std::to_string(p50));
    RecordProperty("ping_error_p99_ms", std::to_string(p99));
    if (!HasFailure()) fs::remove_all(dir);
}

// The NovAtel emulator alone on its pty: silent until asked, <OK / <ERROR with the port prompt
// for each command, only the requested logs at the requested rates, paced at the baud rate.
TEST(HilEmulator, NovatelPtyAnswersCommandsAndSendsOnlyRequestedLogs) {
    namespace nv = pitmap::protocol::novatel;
    using namespace pitmap::sim;
    const fs::path dir =
        fs::path(::testing::TempDir()) / ("pitmap_hil_pty_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    auto sc = BuiltinScenario("demo");
    ASSERT_TRUE(sc.ok());
    sc->track.duration_s = 10.0;
    auto track = SurveyTrack::Plan(*sc);
    ASSERT_TRUE(track.ok());
    const TruthTrajectory truth(*sc, *track);
    const NavErrorModel errors(sc->nav, truth.duration_s(), sc->seed);
    const hil::RealTimeBase time(1.0);
    hil::Manifest manifest;
    ASSERT_TRUE(manifest.Open((dir / "manifest.jsonl").string()).ok());
    hil::NovatelPortConfig cfg;
    cfg.pty_link = (dir / "com1").string();
    cfg.baud = 115200;
    hil::NovatelPortEmulator emu(
        cfg, *sc, truth, errors, pitmap::GpsFromUnix(time.start_unix_us()), time, manifest);
    if (auto s = emu.Open(); !s.ok()) GTEST_SKIP() << s.error().message;
    emu.Start(3.0);
    const int fd = ::open(cfg.pty_link.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    ASSERT_GE(fd, 0);
    termios tio{};
    ::tcgetattr(fd, &tio);
    ::cfmakeraw(&tio);
    ::tcsetattr(fd, TCSANOW, &tio);
    std::vector<std::uint8_t> rx;
    const auto read_until = [&](double t_s) {
        while (time.NowS() < t_s) {
            pollfd p{fd, POLLIN, 0};
            if (::poll(&p, 1, 20) <= 0) continue;
            std::uint8_t buf[4096];
            const ssize_t n = ::read(fd, buf, sizeof(buf));
            if (n > 0) rx.insert(rx.end(), buf, buf + n);
        }
    };
    read_until(0.5);
    EXPECT_TRUE(rx.empty()) << "the receiver talked before any LOG command";
    const std::string cmds =
        "LOG BESTPOSB ONTIME 1\r\nLOG FOOBARB ONNEW\r\nLOG INSPVASB ONTIME 0.1\r\n";
    ASSERT_EQ(::write(fd, cmds.data(), cmds.size()), static_cast<ssize_t>(cmds.size()));
    const double t_cmd = time.NowS();
    read_until(2.45);
    const double t_end = time.NowS();
    emu.Stop();
    ::close(fd);

    nv::Framer framer;
    framer.Push(pitmap::ByteSpan(rx.data(), rx.size()));
    int ok = 0, error = 0, prompts = 0, bestpos = 0, inspvas = 0, others = 0, skipped = 0;
    for (int i = 0; i < 100000; ++i) {
        auto ev = framer.Next();
        if (std::holds_alternative<pitmap::protocol::NeedMore>(ev)) break;
        if (std::holds_alternative<pitmap::protocol::Skipped>(ev)) {
            ++skipped;
            continue;
        }
        const auto& f = std::get<nv::Frame>(ev);
        const std::string text(f.bytes.begin(), f.bytes.end());
        if (f.kind == nv::FrameKind::kPrompt) {
            EXPECT_EQ(text, "[COM1]");
            ++prompts;
        } else if (f.kind == nv::FrameKind::kAbbreviated) {
            (text.rfind("<OK", 0) == 0 ? ok : error) += 1;
        } else if (f.message_id == nv::msg_id::kBestPos) {
            ++bestpos;
        } else if (f.message_id == nv::msg_id::kInsPvaS) {
            ++inspvas;
        } else {
            ++others;
        }
    }
    EXPECT_EQ(skipped, 0);
    EXPECT_EQ(ok, 2);
    EXPECT_EQ(error, 1);
    EXPECT_EQ(prompts, 3);
    EXPECT_EQ(bestpos, 2);        // epochs 1 and 2 s: asked for at 0.5 s
    EXPECT_NEAR(inspvas, 20, 1);  // 10 Hz from 0.5 to 2.4 s (decimated from 50 Hz)
    EXPECT_EQ(others, 0) << "logs nobody asked for";
    // Paced at 115200 bit/s, 8N1: never faster than 11 520 bytes/s.
    EXPECT_LE(static_cast<double>(rx.size()), 11520.0 * (t_end - t_cmd) + 200.0);
    EXPECT_EQ(emu.stats().commands, 3);
    if (!HasFailure()) fs::remove_all(dir);
}
