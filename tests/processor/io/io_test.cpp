// SPDX-License-Identifier: MIT
// Ingest of LCM logs (the reader itself: tests/lcmtypes/lcm_log_reader_test.cpp); empty
// segments; IngestFiles on a mix of .83P, NovAtel and LCM files (every count kept); LAS 1.4
// writer: read back field by field.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <pitmap/ins_pva_t.hpp>
#include <pitmap/multibeam_ping_t.hpp>
#include <pitmap/raw_bytes_t.hpp>

#include "common/byte_io.hpp"
#include "common/gps_time.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/novatel/encoder.hpp"
#include "lcmtypes/log/channels.hpp"
#include "lcmtypes/log/lcm_log_reader.hpp"
#include "processor/io/ingest.hpp"
#include "processor/io/products.hpp"

namespace pitmap::proc::io {
namespace {

void PutBe(std::vector<std::uint8_t>& b, std::uint64_t v, int n) {
    for (int i = n - 1; i >= 0; --i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

std::vector<std::uint8_t> Event(std::int64_t num, const std::string& ch, std::size_t len) {
    std::vector<std::uint8_t> b;
    PutBe(b, lcmlog::kLcmSyncWord, 4);
    PutBe(b, static_cast<std::uint64_t>(num), 8);
    PutBe(b, 1'700'000'000'000'000ull + static_cast<std::uint64_t>(num), 8);
    PutBe(b, ch.size(), 4);
    PutBe(b, len, 4);
    b.insert(b.end(), ch.begin(), ch.end());
    for (std::size_t i = 0; i < len; ++i) b.push_back(static_cast<std::uint8_t>(i));
    return b;
}

std::string WriteFile(const std::string& name, const std::vector<std::uint8_t>& b) {
    const std::string path = ::testing::TempDir() + "/" + name;
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    return path;
}

std::vector<std::uint8_t> EventWith(std::int64_t num,
                                    const std::string& ch,
                                    const std::vector<std::uint8_t>& data) {
    std::vector<std::uint8_t> b;
    PutBe(b, lcmlog::kLcmSyncWord, 4);
    PutBe(b, static_cast<std::uint64_t>(num), 8);
    PutBe(b, 1'700'000'000'000'000ull + static_cast<std::uint64_t>(num), 8);
    PutBe(b, ch.size(), 4);
    PutBe(b, data.size(), 4);
    b.insert(b.end(), ch.begin(), ch.end());
    b.insert(b.end(), data.begin(), data.end());
    return b;
}

template <class T>
std::vector<std::uint8_t> Encode(const T& msg) {
    std::vector<std::uint8_t> b(static_cast<std::size_t>(msg.getEncodedSize()));
    msg.encode(b.data(), 0, static_cast<int>(b.size()));
    return b;
}

std::vector<std::uint8_t> PingBytes(std::int64_t i, int beams) {
    pitmap::multibeam_ping_t m{};
    m.utime = 1'700'000'000'000'000 + i * 100'000;
    m.utime_gps = 1'400'000'000'000'000 + i * 100'000;
    m.ping_number = i;
    m.sound_speed_mps = 1500;
    m.sound_speed_valid = 1;
    m.range_resolution_m = 0.01f;
    m.start_angle_deg = -60;
    m.angle_increment_deg = 1;
    m.num_beams = static_cast<std::int16_t>(beams);
    m.range_counts.assign(static_cast<std::size_t>(beams), 1000);
    return Encode(m);
}

// One MULTIBEAM_PING with num_beams = -1 among 1 200 used to abort `pitmap info` and `pitmap
// run` with "internal error: vector::_M_default_append"; raw events with num_bytes = -5 or
// 0x7fffffff likewise (or allocated 2 GiB). Each is one counted decode failure now.
TEST(Ingest, UndecodableEventsAreCountedAndSkipped) {
    std::vector<std::uint8_t> log;
    for (int i = 0; i < 1200; ++i) {
        auto ping = PingBytes(i, 32);
        if (i == 600) {
            const std::size_t at = ping.size() - 2 - 4 * 32 - 2;  // num_beams
            ping[at] = 0xFF;
            ping[at + 1] = 0xFF;
        }
        const auto e = EventWith(i, "MULTIBEAM_PING_DELTAT_UDP", ping);
        log.insert(log.end(), e.begin(), e.end());
    }
    for (const std::uint32_t bad : {0xFFFFFFFBu, 0x7FFFFFFFu}) {
        pitmap::raw_bytes_t raw{};
        raw.source = "novatel_com1";
        raw.protocol = "novatel";
        raw.transport = pitmap::raw_bytes_t::TRANSPORT_SERIAL;
        raw.num_bytes = 64;
        raw.data.assign(64, 0x20);
        auto bytes = Encode(raw);
        const std::size_t at = bytes.size() - 64 - 4;
        for (int k = 0; k < 4; ++k) bytes[at + k] = static_cast<std::uint8_t>(bad >> (24 - 8 * k));
        const auto e = EventWith(2000, "RAW_NOVATEL_COM1", bytes);
        log.insert(log.end(), e.begin(), e.end());
    }
    IngestConfig cfg;
    auto r = IngestLcmLogs({WriteFile("badcounts.lcmlog", log)}, cfg);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->counts.events, 1202);
    EXPECT_EQ(r->counts.decode_failures, 3);
    EXPECT_EQ(r->pings.pings.size(), 1199u);
    cfg.source = IngestSource::kRaw;
    r = IngestLcmLogs({WriteFile("badcounts.lcmlog", log)}, cfg);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->counts.decode_failures, 2);
}

// The daemon's retry on a full disk once left a 0-byte segment; `pitmap info LOGDIR` then
// refused the whole folder. Empty and too-short files are skipped with a warning.
TEST(Ingest, EmptySegmentsAreSkippedWithAWarning) {
    std::vector<std::uint8_t> log;
    for (int i = 0; i < 10; ++i) {
        const auto e = EventWith(i, "MULTIBEAM_PING_DELTAT_UDP", PingBytes(i, 8));
        log.insert(log.end(), e.begin(), e.end());
    }
    const std::string good = WriteFile("seg-000.lcmlog", log);
    const std::string empty = WriteFile("seg-001.lcmlog", {});
    const std::string tiny = WriteFile("seg-002.lcmlog", {0xED, 0xA1});
    auto r = IngestFiles({good, empty, tiny}, IngestConfig{});
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->counts.files_skipped, 2);
    ASSERT_EQ(r->warnings.size(), 2u);
    EXPECT_NE(r->warnings[0].find("seg-001.lcmlog"), std::string::npos);
    EXPECT_EQ(r->counts.pings, 10);
    // Nothing readable at all is still an error, naming the file.
    // A clean log says nothing more; a damaged one says so.
    auto damaged_log = log;
    damaged_log[30] ^= 0x5A;  // inside the first event's channel name
    auto damaged = IngestFiles({WriteFile("seg-damaged.lcmlog", damaged_log)}, IngestConfig{});
    ASSERT_TRUE(damaged.ok()) << damaged.error().message;
    ASSERT_FALSE(damaged->warnings.empty());
    EXPECT_NE(damaged->warnings.back().find("damaged input"), std::string::npos);
    auto none = IngestFiles({empty}, IngestConfig{});
    ASSERT_FALSE(none.ok());
    EXPECT_NE(none.error().message.find("seg-001.lcmlog"), std::string::npos);
}

// IngestFiles used to copy 4 of the vendor files' counters and drop the others: the same
// capture given twice reported 0 duplicate INS samples. Every count now reaches the result.
TEST(Ingest, VendorFileCountsAreAllKept) {
    const std::string capture = std::string(PITMAP_TEST_DATA_DIR) + "/novatel/oem7drv_ins1.gps";
    std::ifstream in(capture, std::ios::binary);
    const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                          std::istreambuf_iterator<char>());
    const std::string copy = WriteFile("ins1-copy.gps", bytes);
    IngestConfig cfg;
    auto direct = IngestNovatelFiles({capture, copy}, cfg);
    ASSERT_TRUE(direct.ok()) << direct.error().message;
    ASSERT_GT(direct->counts.nav_duplicates, 0);
    auto merged = IngestFiles({capture, copy}, cfg);
    ASSERT_TRUE(merged.ok()) << merged.error().message;
    EXPECT_EQ(merged->counts.nav_duplicates, direct->counts.nav_duplicates);
    EXPECT_EQ(merged->counts.nav_samples, direct->counts.nav_samples);
    EXPECT_EQ(merged->counts.nav_not_good, direct->counts.nav_not_good);
    EXPECT_EQ(merged->counts.nav_without_time, direct->counts.nav_without_time);
    EXPECT_EQ(merged->counts.files, 2);
    EXPECT_EQ(merged->counts.bytes, 2 * static_cast<std::int64_t>(bytes.size()));
}

namespace nv = protocol::novatel;
namespace dt = protocol::deltat;

constexpr std::int64_t kGpsT0 = 2303LL * kMicrosPerWeek + 100'000'000;  // 2024-03

// What a crafted NovAtel stream holds, by Collector's order of checks.
struct NovatelTruth {
    std::int64_t good = 0;
    std::int64_t without_time = 0;  // GPS week 0
    std::int64_t implausible = 0;   // latitude 95 deg: a decode failure
    std::int64_t not_good = 0;      // INS status ALIGNING (with require_good_ins)
};

// `n` INSPVAS at 20 Hz from `t0`, with garbage in between; some without time, some with an
// impossible latitude, some not INS_SOLUTION_GOOD.
std::vector<std::uint8_t> NovatelBytes(int n, std::int64_t t0, NovatelTruth& truth) {
    std::vector<std::uint8_t> buf;
    for (int i = 0; i < n; ++i) {
        const std::int64_t t = t0 + i * 50'000;
        nv::InsPva p;
        p.header.kind = nv::HeaderKind::kShortBinary;
        p.header.message_id = nv::msg_id::kInsPvaS;
        p.header.gps_week = static_cast<std::uint16_t>(t / kMicrosPerWeek);
        p.header.gps_ms = static_cast<std::uint32_t>((t % kMicrosPerWeek) / 1000);
        p.gps_week = i % 10 == 3 ? 0u : static_cast<std::uint32_t>(t / kMicrosPerWeek);
        p.gps_seconds = static_cast<double>(t % kMicrosPerWeek) * 1e-6;
        p.latitude_deg = i % 13 == 5 ? 95.0 : 46.05;
        p.longitude_deg = 14.5;
        p.height_ellipsoid_m = 300;
        p.ins_status = i % 7 == 1 ? nv::InsStatus::kAligning : nv::InsStatus::kSolutionGood;
        if (p.gps_week == 0) {
            ++truth.without_time;
        } else if (p.latitude_deg > 90) {
            ++truth.implausible;
        } else if (p.ins_status != nv::InsStatus::kSolutionGood) {
            ++truth.not_good;
        } else {
            ++truth.good;
        }
        EXPECT_TRUE(nv::EncodeBinary(p, buf));
        if (i % 9 == 0) buf.insert(buf.end(), {'x', 'y', 'z'});
    }
    return buf;
}

// `n` 83P v1.10 pings at 10 Hz (Unix time), every 6th with a garbled header clock, with
// garbage between records.
std::vector<std::uint8_t> File83P(int n, std::int64_t unix0, std::int64_t& garbled) {
    std::vector<std::uint8_t> out;
    for (int i = 0; i < n; ++i) {
        dt::Ping83P p;
        p.format_version = dt::kVersion110;
        dt::SetHeaderTime(p, unix0 + i * 100'000);
        if (i % 6 == 2) {
            const char bad[] = "XX-XXX-XXXX";
            std::copy(std::begin(bad), std::end(bad) - 1, p.date_text.begin());
            ++garbled;
        }
        p.sector_size_deg = 120;
        p.start_angle_cdeg = -6000;
        p.angle_increment_cdeg = 50;
        p.range_resolution_mm = 10;
        p.ping_number = static_cast<std::uint32_t>(i);
        p.range_counts.assign(240, static_cast<std::uint16_t>(900 + i));
        const auto rec = dt::EncodeRecord83P(p);
        out.insert(out.end(), rec.begin(), rec.end());
        if (i % 5 == 4) out.insert(out.end(), {'-', '-'});
    }
    return out;
}

std::vector<std::uint8_t> InsPvaEvent(std::int64_t num, std::int64_t utime_gps, int status) {
    pitmap::ins_pva_t m{};
    m.utime = 1'700'000'000'000'000 + num;
    m.utime_gps = utime_gps;
    m.ins_status = status;
    m.position_type = -1;
    m.latitude_deg = 46.06;
    m.longitude_deg = 14.51;
    m.height_ellipsoid_m = 301;
    return EventWith(num, "INS_PVA_NOV", Encode(m));
}

// Every count that adds up across inputs (Finish() recomputes the sample totals).
void ExpectSum(const IngestCounts& all, const std::vector<const IngestCounts*>& parts) {
#define PITMAP_EXPECT_SUM(field)                             \
    do {                                                     \
        std::int64_t sum = 0;                                \
        for (const IngestCounts* p : parts) sum += p->field; \
        EXPECT_EQ(all.field, sum) << #field;                 \
    } while (false)
    PITMAP_EXPECT_SUM(files);
    PITMAP_EXPECT_SUM(bytes);
    PITMAP_EXPECT_SUM(events);
    PITMAP_EXPECT_SUM(corrupt_events);
    PITMAP_EXPECT_SUM(resync_bytes);
    PITMAP_EXPECT_SUM(truncated_events);
    PITMAP_EXPECT_SUM(length_repairs);
    PITMAP_EXPECT_SUM(files_skipped);
    PITMAP_EXPECT_SUM(decode_failures);
    PITMAP_EXPECT_SUM(nav_samples);
    PITMAP_EXPECT_SUM(nav_without_time);
    PITMAP_EXPECT_SUM(nav_not_good);
    PITMAP_EXPECT_SUM(nav_duplicates);
    PITMAP_EXPECT_SUM(stddev_samples);
    PITMAP_EXPECT_SUM(pings);
    PITMAP_EXPECT_SUM(pings_without_time);
    PITMAP_EXPECT_SUM(pings_bad);
    PITMAP_EXPECT_SUM(ping_duplicates);
    PITMAP_EXPECT_SUM(raw_chunks_decoded);
    PITMAP_EXPECT_SUM(raw_skipped_bytes);
    PITMAP_EXPECT_SUM(raw_decode_errors);
#undef PITMAP_EXPECT_SUM
    std::map<std::string, std::int64_t> by_channel;
    for (const IngestCounts* p : parts) {
        for (const auto& [ch, n] : p->events_by_channel) by_channel[ch] += n;
    }
    EXPECT_EQ(all.events_by_channel, by_channel);
}

// Issue 34: a .83P record cut short (a file copied before the sonar PC finished writing it) is
// a warning naming the file and the byte offset where the record starts, besides the count;
// the whole records before it are kept.
TEST(Ingest83PFiles, RecordCutShortIsAWarningWithTheOffset) {
    std::vector<std::uint8_t> bytes;
    std::size_t last_start = 0;
    for (int i = 0; i < 4; ++i) {
        dt::Ping83P p;
        p.format_version = dt::kVersion110;
        dt::SetHeaderTime(p, 1'709'300'000'000'000 + i * 100'000);
        p.sector_size_deg = 120;
        p.start_angle_cdeg = -6000;
        p.angle_increment_cdeg = 50;
        p.range_resolution_mm = 10;
        p.ping_number = static_cast<std::uint32_t>(i);
        p.range_counts.assign(240, 900);
        const auto rec = dt::EncodeRecord83P(p);
        last_start = bytes.size();
        bytes.insert(bytes.end(), rec.begin(), rec.end());
    }
    const std::size_t cut = (bytes.size() - last_start) / 2;
    // erase, not resize(size - cut): GCC 12 at -O1 cannot bound the size and warns that
    // resize's fill may exceed any object (-Wstringop-overflow, a false positive).
    bytes.erase(bytes.end() - static_cast<std::ptrdiff_t>(cut), bytes.end());
    const std::string path = WriteFile("cut.83P", bytes);
    IngestResult r;
    ASSERT_TRUE(Ingest83PFiles({path}, {}, -1, r).ok());
    EXPECT_EQ(r.pings.pings.size(), 3u);
    EXPECT_EQ(r.counts.raw_skipped_bytes, static_cast<std::int64_t>(bytes.size() - last_start));
    ASSERT_EQ(r.warnings.size(), 1u);
    const std::string& w = r.warnings[0];
    EXPECT_NE(w.find(path), std::string::npos) << w;
    EXPECT_NE(w.find("cut short"), std::string::npos) << w;
    EXPECT_NE(w.find("byte offset " + std::to_string(last_start)), std::string::npos) << w;
}

// Issue 16: IngestFiles on a mix of a .83P file, a NovAtel file and an LCM log keeps every
// count of each input (and each is non-zero, so a dropped one shows).
TEST(IngestFiles, MixOf83PNovatelAndLcmKeepsEveryCount) {
    NovatelTruth nov_truth;
    const std::string nov = WriteFile("mix-ins.gps", NovatelBytes(200, kGpsT0, nov_truth));
    std::int64_t garbled = 0;
    const std::string p83 = WriteFile("mix-sonar.83P", File83P(60, 1'709'300'000'000'000, garbled));
    std::vector<std::uint8_t> log;
    std::int64_t num = 0;
    for (int i = 0; i < 40; ++i) {
        // 4 without time, 8 not good, 28 good, at times the NovAtel file does not have.
        const std::int64_t t = i % 10 == 0 ? 0 : kGpsT0 + 20'000'000 + i * 10'000;
        const auto e = InsPvaEvent(num++, t, i % 5 == 1 ? 1 : 3);
        log.insert(log.end(), e.begin(), e.end());
    }
    for (int i = 0; i < 30; ++i) {
        auto ping = PingBytes(i, 32);
        if (i == 7) {
            const std::size_t at = ping.size() - 2 - 4 * 32 - 2;  // num_beams = -1
            ping[at] = 0xFF;
            ping[at + 1] = 0xFF;
        }
        const auto e = EventWith(num++, "MULTIBEAM_PING_DELTAT_UDP", ping);
        log.insert(log.end(), e.begin(), e.end());
    }
    const std::string lcm = WriteFile("mix-log.lcmlog", log);

    IngestConfig cfg;
    cfg.require_good_ins = true;
    // The fixtures' positions are not one vehicle's track (the log's lie 1.4 km from the
    // NovAtel file's, 10 s later): only their counts are under test here, not the sessions.
    cfg.max_session_speed_mps = 1e6;
    auto a = IngestLcmLogs({lcm}, cfg);
    ASSERT_TRUE(a.ok()) << a.error().message;
    auto b = IngestNovatelFiles({nov}, cfg);
    ASSERT_TRUE(b.ok()) << b.error().message;
    IngestResult c;
    ASSERT_TRUE(Ingest83PFiles({p83}, cfg, -1, c).ok());
    // Ingest83PFiles adds to a result that the caller finishes: count its pings here.
    c.counts.pings = static_cast<std::int64_t>(c.pings.pings.size());

    // Each input on its own: the counts the construction says.
    EXPECT_EQ(a->counts.nav_without_time, 4);
    EXPECT_EQ(a->counts.nav_not_good, 8);
    EXPECT_EQ(a->counts.nav_samples, 28);
    EXPECT_EQ(a->counts.decode_failures, 1);
    EXPECT_EQ(a->counts.pings, 29);
    EXPECT_EQ(b->counts.nav_without_time, nov_truth.without_time);
    EXPECT_EQ(b->counts.decode_failures, nov_truth.implausible);
    EXPECT_EQ(b->counts.nav_not_good, nov_truth.not_good);
    EXPECT_EQ(b->counts.nav_samples, nov_truth.good);
    EXPECT_GT(b->counts.raw_skipped_bytes, 0);
    EXPECT_EQ(c.counts.pings_without_time, garbled);
    EXPECT_EQ(c.counts.pings, 60 - garbled);
    EXPECT_GT(c.counts.raw_skipped_bytes, 0);
    for (std::int64_t n :
         {nov_truth.without_time, nov_truth.implausible, nov_truth.not_good, garbled}) {
        EXPECT_GT(n, 0);
    }

    // Together, in any order: every count is the sum.
    for (const auto& files :
         {std::vector<std::string>{p83, nov, lcm}, std::vector<std::string>{lcm, p83, nov}}) {
        auto all = IngestFiles(files, cfg);
        ASSERT_TRUE(all.ok()) << all.error().message;
        ExpectSum(all->counts, {&a->counts, &b->counts, &c.counts});
        EXPECT_EQ(all->nav.samples.size(), static_cast<std::size_t>(28 + nov_truth.good));
        EXPECT_EQ(all->pings.pings.size(), static_cast<std::size_t>(29 + 60 - garbled));
    }
}

// Issue 17 item 6: the per-beam intensities reach the ping series from LCM logs and .83P
// files, beside the range counts; a ping without any gets zeros, and a survey whose pings have
// none (83P v1.00) has no intensities at all.
TEST(Ingest, IntensitiesComeThroughBesideTheRanges) {
    std::vector<std::uint8_t> log;
    for (int i = 0; i < 6; ++i) {
        pitmap::multibeam_ping_t m{};
        m.utime = 1'700'000'000'000'000 + i * 100'000;
        m.utime_gps = 1'400'000'000'000'000 + i * 100'000;
        m.ping_number = i;
        m.range_resolution_m = 0.01f;
        m.start_angle_deg = -60;
        m.angle_increment_deg = 1;
        m.num_beams = 8;
        m.range_counts.assign(8, 1000);
        // Ping 0: none; ping 3 claims intensities of the wrong count (kept without them);
        // ping 5: a value beyond 16 bits and a negative one (clamped).
        if (i != 0) {
            m.intensity_included = 1;
            m.num_intensities = static_cast<std::int16_t>(i == 3 ? 7 : 8);
            for (int b = 0; b < m.num_intensities; ++b) m.intensities.push_back(100 * i + b);
            if (i == 5) {
                m.intensities[0] = 70000;
                m.intensities[1] = -4;
            }
        }
        const auto e = EventWith(i, "MULTIBEAM_PING_DELTAT_UDP", Encode(m));
        log.insert(log.end(), e.begin(), e.end());
    }
    auto a = IngestLcmLogs({WriteFile("intensity.lcmlog", log)}, {});
    ASSERT_TRUE(a.ok()) << a.error().message;
    const auto& p = a->pings;
    ASSERT_EQ(p.pings.size(), 6u);
    ASSERT_EQ(p.intensities.size(), p.range_counts.size());
    for (int i = 0; i < 6; ++i) {
        for (int b = 0; b < 8; ++b) {
            const std::uint16_t got = p.intensities[p.pings[i].beam_offset + b];
            std::uint16_t want = (i == 0 || i == 3) ? 0 : static_cast<std::uint16_t>(100 * i + b);
            if (i == 5 && b == 0) want = 65535;
            if (i == 5 && b == 1) want = 0;
            EXPECT_EQ(got, want) << "ping " << i << " beam " << b;
        }
    }

    // .83P: v1.10 with intensities, v1.00 (which has no field for them) without.
    const auto file = [](std::uint8_t version, bool with) {
        std::vector<std::uint8_t> out;
        for (int i = 0; i < 5; ++i) {
            dt::Ping83P q;
            q.format_version = version;
            dt::SetHeaderTime(q, 1'709'300'000'000'000 + i * 100'000);
            q.sector_size_deg = 120;
            q.start_angle_cdeg = -6000;
            q.angle_increment_cdeg = 50;
            q.range_resolution_mm = 10;
            q.ping_number = static_cast<std::uint32_t>(i);
            q.range_counts.assign(240, 900);
            q.intensity_included = with;
            if (with) {
                for (int b = 0; b < 240; ++b)
                    q.intensities.push_back(static_cast<std::uint16_t>(5000 + 10 * i + b));
            }
            const auto rec = dt::EncodeRecord83P(q);
            out.insert(out.end(), rec.begin(), rec.end());
        }
        return out;
    };
    IngestResult v110;
    ASSERT_TRUE(
        Ingest83PFiles({WriteFile("i110.83P", file(dt::kVersion110, true))}, {}, 18, v110).ok());
    ASSERT_EQ(v110.pings.pings.size(), 5u);
    ASSERT_EQ(v110.pings.intensities.size(), v110.pings.range_counts.size());
    EXPECT_EQ(v110.pings.intensities[0], 5000);
    EXPECT_EQ(v110.pings.intensities[v110.pings.pings[4].beam_offset + 239], 5000 + 40 + 239);
    IngestResult v100;
    ASSERT_TRUE(
        Ingest83PFiles({WriteFile("i100.83P", file(dt::kVersion100, false))}, {}, 18, v100).ok());
    EXPECT_EQ(v100.pings.pings.size(), 5u);
    EXPECT_FALSE(v100.pings.has_intensities());
}

// IngestFiles on LCM logs alone equals IngestLcmLogs, and the same NovAtel file twice counts
// its samples as duplicates while keeping the other counts doubled.
TEST(IngestFiles, LcmLogsAndRepeatedVendorFiles) {
    std::vector<std::uint8_t> log;
    for (int i = 0; i < 12; ++i) {
        const auto e =
            InsPvaEvent(i, i % 4 == 0 ? 0 : kGpsT0 + 7'000'000 + i * 10'000, i % 3 == 0 ? 2 : 3);
        log.insert(log.end(), e.begin(), e.end());
    }
    const std::string seg0 = WriteFile("lcm-only-0.lcmlog", log);
    const std::string seg1 = WriteFile("lcm-only-1.lcmlog", Event(99, "OTHER", 5));
    IngestConfig cfg;
    cfg.require_good_ins = true;
    // The fixtures' positions are not one vehicle's track (the log's lie 1.4 km from the
    // NovAtel file's, 10 s later): only their counts are under test here, not the sessions.
    cfg.max_session_speed_mps = 1e6;
    auto direct = IngestLcmLogs({seg0, seg1}, cfg);
    ASSERT_TRUE(direct.ok());
    auto files = IngestFiles({seg1, seg0}, cfg);
    ASSERT_TRUE(files.ok());
    ExpectSum(files->counts, {&direct->counts});
    EXPECT_EQ(direct->counts.nav_without_time, 3);
    EXPECT_EQ(direct->counts.nav_not_good, 3);  // i = 3, 6, 9
    EXPECT_EQ(direct->counts.files, 2);

    NovatelTruth truth;
    const std::string nov = WriteFile("twice.gps", NovatelBytes(100, kGpsT0, truth));
    auto once = IngestNovatelFiles({nov}, cfg);
    ASSERT_TRUE(once.ok());
    auto twice = IngestFiles({nov, nov, seg0}, cfg);
    ASSERT_TRUE(twice.ok());
    EXPECT_EQ(twice->counts.nav_without_time,
              2 * once->counts.nav_without_time + direct->counts.nav_without_time);
    EXPECT_EQ(twice->counts.nav_not_good,
              2 * once->counts.nav_not_good + direct->counts.nav_not_good);
    EXPECT_EQ(twice->counts.decode_failures, 2 * once->counts.decode_failures);
    EXPECT_EQ(twice->counts.nav_duplicates, once->counts.nav_samples);
    EXPECT_EQ(twice->counts.nav_samples, once->counts.nav_samples + direct->counts.nav_samples);
    EXPECT_EQ(twice->counts.files, 3);
}

// A log with raw NovAtel chunks only (no decoded INS channel) and one undecodable raw event:
// in auto mode the raw channel is read twice, and the bad event is still counted once.
TEST(Ingest, AutoModeCountsAnUndecodableRawEventOnce) {
    NovatelTruth truth;
    const auto bytes = NovatelBytes(60, kGpsT0, truth);
    std::vector<std::uint8_t> log;
    std::int64_t num = 0;
    for (std::size_t pos = 0, k = 0; pos < bytes.size(); ++k) {
        const std::size_t n = std::min<std::size_t>(97 + 31 * (k % 5), bytes.size() - pos);
        pitmap::raw_bytes_t raw{};
        raw.utime = 1'700'000'000'000'000 + num;
        raw.source = "nov";
        raw.protocol = std::string(lcmlog::kProtocolNovatel);
        raw.transport = pitmap::raw_bytes_t::TRANSPORT_SERIAL;
        raw.seq = static_cast<std::int64_t>(k);
        raw.data.assign(bytes.begin() + static_cast<long>(pos),
                        bytes.begin() + static_cast<long>(pos + n));
        raw.num_bytes = static_cast<std::int32_t>(n);
        auto enc = Encode(raw);
        if (k == 3) {
            // num_bytes = 0x7fffffff: the event does not decode.
            const std::size_t at = enc.size() - n - 4;
            enc[at] = 0x7F;
            enc[at + 1] = enc[at + 2] = enc[at + 3] = 0xFF;
        }
        const auto e = EventWith(num++, "RAW_NOV", enc);
        log.insert(log.end(), e.begin(), e.end());
        pos += n;
    }
    const std::string path = WriteFile("raw-only.lcmlog", log);
    IngestConfig cfg;
    cfg.source = IngestSource::kRaw;
    auto raw = IngestLcmLogs({path}, cfg);
    ASSERT_TRUE(raw.ok());
    auto automatic = IngestLcmLogs({path}, IngestConfig{});
    ASSERT_TRUE(automatic.ok());
    EXPECT_TRUE(automatic->nav_from_raw);
    // The bad event plus the implausible INS samples in the chunks that decoded.
    EXPECT_GE(raw->counts.decode_failures, 1);
    EXPECT_EQ(automatic->counts.decode_failures, raw->counts.decode_failures);
    EXPECT_EQ(automatic->counts.nav_without_time, raw->counts.nav_without_time);
    EXPECT_EQ(automatic->counts.nav_samples, raw->counts.nav_samples);
    EXPECT_EQ(automatic->counts.events, raw->counts.events);
    EXPECT_GT(raw->counts.nav_samples, 0);
}

TEST(Ingest, LogWithoutSensorChannelsGivesEmptySeries) {
    auto e = Event(0, "OTHER", 3);
    auto r = IngestLcmLogs({WriteFile("other.lcmlog", e)}, IngestConfig{});
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->counts.events, 1);
    EXPECT_TRUE(r->nav.samples.empty());
    EXPECT_TRUE(r->pings.pings.empty());
    EXPECT_FALSE(IngestLcmLogs({}, IngestConfig{}).ok());
}

TEST(Las, ReadsBackFieldByField) {
    georef::GeorefResult g;
    g.world_origin = {40.4435, -7.7806, 412.0};
    georef::GeorefPing ping;
    ping.utime_gps = 1'465'500'000'123'456;
    g.pings.push_back(ping);
    for (int i = 0; i < 2; ++i) {
        g.points.position_world.emplace_back(i * 1.0, 2.0, -10.0);
        g.points.ping.push_back(0);
        g.points.beam.push_back(static_cast<std::uint16_t>(i));
        g.points.range_m.push_back(10.0f);
        g.points.angle_rad.push_back(i == 0 ? -0.5f : 0.5f);
    }
    auto utm = georef::ToUtm(g);
    ASSERT_TRUE(utm.ok());
    EXPECT_EQ(utm->zone, 29);
    EXPECT_EQ(utm->epsg, 32629);
    const std::string path = ::testing::TempDir() + "/p.las";
    ASSERT_TRUE(WriteLas(path, g, *utm).ok());
    std::ifstream in(path, std::ios::binary);
    std::vector<std::uint8_t> b((std::istreambuf_iterator<char>(in)), {});
    ByteReader r(b);
    EXPECT_EQ(r.FixedString(4), "LASF");
    r.Seek(6);
    EXPECT_EQ(r.U16Le(), 0x11);  // adjusted GPS time + WKT
    r.Seek(24);
    EXPECT_EQ(r.U8(), 1);
    EXPECT_EQ(r.U8(), 4);
    r.Seek(94);
    EXPECT_EQ(r.U16Le(), 375);
    const std::uint32_t point_offset = r.U32Le();
    EXPECT_EQ(r.U32Le(), 1u);  // one VLR
    EXPECT_EQ(r.U8(), 6);
    EXPECT_EQ(r.U16Le(), 30);
    EXPECT_EQ(r.U32Le(), 0u);  // legacy count
    r.Seek(131);
    const double sx = r.F64Le();
    r.Seek(155);
    const double ox = r.F64Le(), oy = r.F64Le(), oz = r.F64Le();
    EXPECT_DOUBLE_EQ(sx, 0.001);
    r.Seek(247);
    EXPECT_EQ(r.U64Le(), 2u);
    // VLR
    r.Seek(375 + 2);
    EXPECT_EQ(r.FixedString(16).substr(0, 15), "LASF_Projection");
    EXPECT_EQ(r.U16Le(), 2112);
    const std::uint16_t wkt_len = r.U16Le();
    r.Skip(32);
    const std::string wkt = r.FixedString(wkt_len);
    EXPECT_NE(wkt.find("UTM zone 29N"), std::string::npos);
    EXPECT_EQ(point_offset, 375u + 54u + wkt_len);
    // Points.
    r.Seek(point_offset);
    for (int i = 0; i < 2; ++i) {
        const double x = r.I32Le() * 0.001 + ox;
        const double y = r.I32Le() * 0.001 + oy;
        const double z = r.I32Le() * 0.001 + oz;
        EXPECT_NEAR(x, utm->easting_northing_height[i].x(), 0.001);
        EXPECT_NEAR(y, utm->easting_northing_height[i].y(), 0.001);
        EXPECT_NEAR(z, utm->easting_northing_height[i].z(), 0.001);
        r.Skip(2);
        EXPECT_EQ(r.U8(), 0x11);
        r.Skip(3);
        EXPECT_NEAR(r.I16Le() * 0.006, i == 0 ? -28.65 : 28.65, 0.01);
        r.Skip(2);
        EXPECT_NEAR(r.F64Le(), 1'465'500'000.123456 - 1e9, 1e-6);
    }
    EXPECT_EQ(r.position(), b.size());
    EXPECT_TRUE(r.ok());
}

}  // namespace
}  // namespace pitmap::proc::io
