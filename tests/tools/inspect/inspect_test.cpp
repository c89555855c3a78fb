// SPDX-License-Identifier: MIT
// pitmap-inspect's library on crafted inputs: format detection, chunking invariance, .83P
// files, UDP 83P captures, pitmap LCM logs (raw channels framed once, decoded channels counted
// by type), and bad inputs.
#include "tools/inspect/inspect.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <lcm/lcm-cpp.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/byte_io.hpp"
#include "common/capture/capture.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "pitmap/gnss_position_t.hpp"
#include "pitmap/raw_bytes_t.hpp"
#include "tests/protocol/novatel/test_util.hpp"

namespace pitmap::tools::inspect {
namespace {

namespace fs = std::filesystem;
namespace deltat = protocol::deltat;

const fs::path kNovatelDir = fs::path(PITMAP_TEST_DATA_DIR) / "novatel";

std::vector<std::uint8_t> Text(const std::string& s) {
    return {s.begin(), s.end()};
}

std::vector<std::uint8_t> ReadBytes(const fs::path& path) {
    auto bytes = capture::ReadFileBytes(path.string());
    EXPECT_TRUE(bytes.ok()) << (bytes.ok() ? "" : bytes.error().message);
    return bytes.ok() ? *bytes : std::vector<std::uint8_t>{};
}

class TempFile {
public:
    explicit TempFile(const std::string& name)
        : path_((fs::temp_directory_path() / (std::to_string(::getpid()) + "_inspect_" + name))
                    .string()) {}
    ~TempFile() { std::remove(path_.c_str()); }
    const std::string& path() const { return path_; }
    void Write(const std::vector<std::uint8_t>& bytes) const {
        std::ofstream out(path_, std::ios::binary);
        out.write(reinterpret_cast<const char*>(bytes.data()),
                  static_cast<std::streamsize>(bytes.size()));
    }

private:
    std::string path_;
};

deltat::Ping83P MakePing(std::int64_t utime, std::uint32_t ping_number) {
    deltat::Ping83P ping;
    ping.format_version = deltat::kVersion110;
    deltat::SetHeaderTime(ping, utime);
    ping.range_counts.assign(120, 1000);
    ping.range_resolution_mm = 10;
    ping.angle_increment_cdeg = 100;
    ping.start_angle_cdeg = -6000;
    ping.ping_number = ping_number;
    return ping;
}

// ---- Detection -----------------------------------------------------------------------------

TEST(DetectFormatTest, MagicNumbersAndMarkers) {
    const auto check = [](const std::vector<std::uint8_t>& bytes,
                          const std::string& name,
                          InputFormat format,
                          Protocol protocol) {
        const auto d = DetectFormat(bytes, name);
        ASSERT_TRUE(d.ok()) << name << ": " << d.error().message;
        EXPECT_EQ(d->format, format) << name;
        if (format == InputFormat::kRaw) {
            EXPECT_EQ(d->protocol, protocol) << name;
        }
    };
    check({0xD4, 0xC3, 0xB2, 0xA1, 2, 0}, "a.pcap", InputFormat::kPcap, Protocol::kAuto);
    check({0xA1, 0xB2, 0xC3, 0xD4, 0, 2}, "b", InputFormat::kPcap, Protocol::kAuto);
    check({0x4D, 0x3C, 0xB2, 0xA1, 2, 0}, "ns.pcap", InputFormat::kPcap, Protocol::kAuto);
    check({0x0A, 0x0D, 0x0D, 0x0A, 0, 0}, "c.pcapng", InputFormat::kPcap, Protocol::kAuto);
    check({0xED, 0xA1, 0xDA, 0x01, 0, 0}, "lcmlog-2024", InputFormat::kLcmLog, Protocol::kAuto);
    check(Text("83P\x0a..."), "ping.bin", InputFormat::kRaw, Protocol::kDeltaT);
    check(Text("anything"), "survey.83p", InputFormat::kRaw, Protocol::kDeltaT);
    check({0x00, 0x01, 0xAA, 0x44, 0x12, 0x1C}, "x.bin", InputFormat::kRaw, Protocol::kNovatel);
    check({0xAA, 0x44, 0x13, 0x58}, "x.bin", InputFormat::kRaw, Protocol::kNovatel);
    check(Text("junk #BESTPOSA,COM1,0,83.5,FINE"), "x.asc", InputFormat::kRaw, Protocol::kNovatel);
    check(Text("\r\n<OK\r\n[COM1]"), "x.txt", InputFormat::kRaw, Protocol::kNovatel);
    // The real files are detected too.
    for (const char* name :
         {"oem7drv_bestpos.gps", "gavlab_OneEach.ASC", "gavlab_test2_rcvr1.dat"}) {
        check(ReadBytes(kNovatelDir / name), name, InputFormat::kRaw, Protocol::kNovatel);
    }
    check(ReadBytes(kNovatelDir / "spandrv_propak6-basic-fix.pcap.gz"),
          "gz",
          InputFormat::kPcap,
          Protocol::kAuto);
}

TEST(DetectFormatTest, UnknownAndEmptyAreErrorsNamingTheFile) {
    const auto unknown = DetectFormat(Text("hello world, this is text #not a log"), "notes.txt");
    ASSERT_FALSE(unknown.ok());
    EXPECT_NE(unknown.error().message.find("notes.txt"), std::string::npos);
    const auto empty = DetectFormat({}, "empty.gps");
    ASSERT_FALSE(empty.ok());
    EXPECT_NE(empty.error().message.find("empty.gps"), std::string::npos);
}

TEST(ParseOptionsTest, Spellings) {
    EXPECT_EQ(ParseInputFormat("pcap"), InputFormat::kPcap);
    EXPECT_EQ(ParseInputFormat("lcm"), InputFormat::kLcmLog);
    EXPECT_EQ(ParseInputFormat("83p"), InputFormat::kRaw);
    EXPECT_FALSE(ParseInputFormat("gps"));
    EXPECT_EQ(ParseProtocol("deltat"), Protocol::kDeltaT);
    EXPECT_EQ(ParseProtocol("novatel"), Protocol::kNovatel);
    EXPECT_FALSE(ParseProtocol("nmea"));
}

// ---- Raw streams ---------------------------------------------------------------------------

TEST(InspectStreamTest, CountsDoNotDependOnChunkSize) {
    const auto bytes = ReadBytes(kNovatelDir / "oem7drv_bestpos.gps");
    InspectOptions options;
    options.chunk_bytes = 4096;
    const SourceSummary whole = InspectStream(bytes, Protocol::kNovatel, options, "file");
    EXPECT_EQ(whole.frames_total, 42u);
    EXPECT_EQ(whole.frames_by_id.at("42"), 5u);
    EXPECT_EQ(whole.frames_by_id.at("OK"), 8u);
    for (std::size_t chunk : {1u, 2u, 3u, 7u, 28u, 100u}) {
        options.chunk_bytes = chunk;
        const SourceSummary s = InspectStream(bytes, Protocol::kNovatel, options, "file");
        EXPECT_EQ(s.frames_by_id, whole.frames_by_id) << chunk;
        EXPECT_EQ(s.skipped.bytes, whole.skipped.bytes) << chunk;
        EXPECT_EQ(s.bytes, bytes.size()) << chunk;
        EXPECT_EQ(s.chunks, (bytes.size() + chunk - 1) / chunk) << chunk;
    }
}

TEST(InspectStreamTest, EveryByteIsAFrameOrSkipped) {
    // A frame, garbage, a cut-off frame at the end.
    auto bytes = ReadBytes(kNovatelDir / "oem7drv_rxstatus.gps");  // 3 x RXSTATUS, 360 bytes
    ASSERT_EQ(bytes.size(), 360u);
    std::vector<std::uint8_t> stream(bytes.begin(), bytes.begin() + 120);
    for (int i = 0; i < 10; ++i) stream.push_back(0x55);
    stream.insert(stream.end(), bytes.begin() + 120, bytes.end());
    stream.insert(stream.end(), bytes.begin(), bytes.begin() + 50);  // cut inside a frame
    InspectOptions options;
    const SourceSummary s = InspectStream(stream, Protocol::kNovatel, options, "file");
    EXPECT_EQ(s.frames_by_id.at("93"), 3u);
    EXPECT_EQ(s.skipped.Bytes(protocol::SkipReason::kGarbage), 10u);
    EXPECT_EQ(s.truncated_tail_bytes, 50u);
    EXPECT_EQ(s.skipped.TotalBytes(), 60u);
    EXPECT_EQ(s.crc_failures, 0u);
}

// A false long header (`AA 44 12 1C`, length claiming 30 000 bytes) two thirds into a real
// INS capture: pitmap-inspect found 137 of 284 frames; every frame is found now, in any chunking.
TEST(InspectStreamTest, FalseLongHeaderBeforeTheEndHidesNoFrame) {
    const auto clean = ReadBytes(kNovatelDir / "oem7drv_ins1.gps");
    InspectOptions options;
    const SourceSummary whole = InspectStream(clean, Protocol::kNovatel, options, "file");
    std::uint64_t clean_frames = 0;
    for (const auto& [id, n] : whole.frames_by_id) clean_frames += n;
    ASSERT_EQ(clean_frames, 284u);
    // Insert at a frame boundary: after the first frame of id 1362 past the middle.
    const auto fake = protocol::novatel::testing::FalseLongHeader();
    std::size_t at = clean.size() / 2;
    while (!(clean[at] == 0xAA && clean[at + 1] == 0x44 && clean[at + 2] == 0x13)) ++at;
    std::vector<std::uint8_t> dirty(clean.begin(), clean.begin() + static_cast<long>(at));
    dirty.insert(dirty.end(), fake.begin(), fake.end());
    dirty.insert(dirty.end(), clean.begin() + static_cast<long>(at), clean.end());
    for (std::size_t chunk : {1u, 512u, 65536u}) {
        options.chunk_bytes = chunk;
        const SourceSummary s = InspectStream(dirty, Protocol::kNovatel, options, "file");
        EXPECT_EQ(s.frames_by_id, whole.frames_by_id) << chunk;
        EXPECT_EQ(s.skipped.TotalBytes(), 28u) << chunk;
    }
}

TEST(InspectStreamTest, CorruptedCrcIsCounted) {
    auto bytes = ReadBytes(kNovatelDir / "oem7drv_rxstatus.gps");
    bytes[60] ^= 0x01;  // inside the first frame's body
    const SourceSummary s = InspectStream(bytes, Protocol::kNovatel, InspectOptions{}, "file");
    EXPECT_EQ(s.crc_failures, 1u);
    EXPECT_EQ(s.frames_by_id.at("93"), 2u);
}

TEST(InspectFileTest, Deltat83pFileWithGarbageBetweenRecords) {
    std::vector<std::uint8_t> file;
    const std::int64_t t0 = 1'700'000'000'000'000;
    for (std::uint32_t i = 0; i < 3; ++i) {
        const auto record = deltat::EncodeRecord83P(MakePing(t0 + i * 250'000, i));
        ASSERT_FALSE(record.empty());
        file.insert(file.end(), record.begin(), record.end());
        if (i == 0) file.insert(file.end(), {'x', 'y', 'z', 'z', 'y'});
    }
    const auto comment = deltat::EncodeComment83P("line 12 start");
    file.insert(file.end(), comment.begin(), comment.end());
    TempFile tmp("survey.83P");
    tmp.Write(file);

    const auto report = InspectFile(tmp.path(), InspectOptions{});
    ASSERT_TRUE(report.ok()) << report.error().message;
    EXPECT_EQ(report->format, InputFormat::kRaw);
    const SourceSummary& s = report->total;
    EXPECT_EQ(s.protocol, "");
    ASSERT_EQ(report->sources.size(), 1u);
    EXPECT_EQ(report->sources[0].protocol, "deltat_83p");
    EXPECT_EQ(s.frames_by_id.at("83P"), 3u);
    EXPECT_EQ(s.frames_by_id.at("83P_COMMENT"), 1u);
    EXPECT_EQ(s.log_frames, 3u);
    EXPECT_EQ(s.skipped.TotalBytes(), 5u);
    ASSERT_TRUE(s.sonar_start_utime && s.sonar_end_utime);
    EXPECT_EQ(*s.sonar_start_utime, t0);
    EXPECT_EQ(*s.sonar_end_utime, t0 + 500'000);
    const auto json = ToJson(*report);
    EXPECT_EQ(json.at("frames_by_id").at("83P"), 3);
    EXPECT_DOUBLE_EQ(json.at("time_span").at("duration_s").get<double>(), 0.5);
    EXPECT_EQ(json.at("file"), fs::path(tmp.path()).filename().string());
}

// ---- Captures with UDP 83P datagrams --------------------------------------------------------

std::vector<std::uint8_t> UdpPacket(const std::vector<std::uint8_t>& payload) {
    std::vector<std::uint8_t> out(12, 0x22);
    ByteWriter w(out);
    w.U16Be(0x0800);
    w.U8(0x45);
    w.U8(0);
    w.U16Be(static_cast<std::uint16_t>(20 + 8 + payload.size()));
    w.U32Be(0);
    w.U8(64);
    w.U8(17);
    w.U16Be(0);
    w.U32Be(0xC0A80064);  // 192.168.0.100, the sonar
    w.U32Be(0xC0A80001);
    w.U16Be(4040);
    w.U16Be(4040);
    w.U16Be(static_cast<std::uint16_t>(8 + payload.size()));
    w.U16Be(0);
    w.Bytes(payload);
    return out;
}

TEST(InspectFileTest, UdpDatagramsOf83pRecords) {
    std::vector<std::uint8_t> pcap;
    ByteWriter w(pcap);
    w.U32Le(0xA1B2C3D4u);
    w.U16Le(2);
    w.U16Le(4);
    w.U32Le(0);
    w.U32Le(0);
    w.U32Le(65535);
    w.U32Le(1);
    const auto add = [&](std::uint32_t sec, const std::vector<std::uint8_t>& packet) {
        w.U32Le(sec);
        w.U32Le(0);
        w.U32Le(static_cast<std::uint32_t>(packet.size()));
        w.U32Le(static_cast<std::uint32_t>(packet.size()));
        w.Bytes(packet);
    };
    const auto r0 = deltat::EncodeRecord83P(MakePing(1'700'000'000'000'000, 0));
    const auto r1 = deltat::EncodeRecord83P(MakePing(1'700'000'000'100'000, 1));
    add(1, UdpPacket(r0));
    add(2, UdpPacket(std::vector<std::uint8_t>(r1.begin(), r1.begin() + 300)));  // cut short
    add(3, UdpPacket(r1));
    TempFile tmp("sonar.pcap");
    tmp.Write(pcap);

    const auto report = InspectFile(tmp.path(), InspectOptions{});
    ASSERT_TRUE(report.ok()) << report.error().message;
    ASSERT_EQ(report->sources.size(), 1u);
    EXPECT_EQ(report->sources[0].protocol, "deltat_83p");
    EXPECT_EQ(report->sources[0].chunks, 3u);
    EXPECT_EQ(report->total.frames_by_id.at("83P"), 2u);
    EXPECT_EQ(report->total.datagram_errors, 1u);
    EXPECT_EQ(report->total.skipped.Bytes(protocol::SkipReason::kTruncated), 300u);
    ASSERT_TRUE(report->capture);
    EXPECT_EQ(report->capture->udp_datagrams, 3u);
}

// ---- LCM logs ------------------------------------------------------------------------------

void WriteEvent(lcm::LogFile& log,
                std::int64_t utime,
                const std::string& channel,
                const std::vector<std::uint8_t>& data) {
    lcm::LogEvent ev{};
    ev.timestamp = utime;
    ev.channel = channel;
    ev.datalen = static_cast<std::int32_t>(data.size());
    ev.data = const_cast<std::uint8_t*>(data.data());
    ASSERT_EQ(log.writeEvent(&ev), 0);
}

template <typename Msg>
std::vector<std::uint8_t> Encode(const Msg& m) {
    std::vector<std::uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(buf.data(), 0, static_cast<int>(buf.size()));
    return buf;
}

pitmap::raw_bytes_t Raw(const std::string& source,
                        const std::string& protocol_name,
                        std::int8_t transport,
                        std::int64_t seq,
                        const std::uint8_t* data,
                        std::size_t n) {
    pitmap::raw_bytes_t raw{};
    raw.utime = 1'700'000'000'000'000 + seq;
    raw.source = source;
    raw.protocol = protocol_name;
    raw.transport = transport;
    raw.seq = seq;
    raw.num_bytes = static_cast<std::int32_t>(n);
    raw.data.assign(data, data + n);
    return raw;
}

TEST(InspectFileTest, LcmLogFramesRawChannelsOnceAndCountsTheOthers) {
    const auto novatel = ReadBytes(kNovatelDir / "oem7drv_bestpos.gps");  // 42 frames
    TempFile tmp("log.lcm");
    {
        lcm::LogFile log(tmp.path(), "w");
        ASSERT_TRUE(log.good());
        // The NovAtel bytes in odd chunks (frames straddle events); seq 5 is missing.
        std::int64_t seq = 0;
        for (std::size_t off = 0; off < novatel.size(); off += 333) {
            if (seq == 5) ++seq;
            const std::size_t n = std::min<std::size_t>(333, novatel.size() - off);
            WriteEvent(log,
                       1000 + seq,
                       "RAW_NOVATEL_COM1",
                       Encode(Raw("novatel_com1",
                                  "novatel",
                                  pitmap::raw_bytes_t::TRANSPORT_SERIAL,
                                  seq,
                                  novatel.data() + off,
                                  n)));
            ++seq;
        }
        // Two sonar datagrams.
        for (std::int64_t i = 0; i < 2; ++i) {
            const auto rec = deltat::EncodeRecord83P(MakePing(1'700'000'000'000'000 + i, 0));
            WriteEvent(log,
                       2000 + i,
                       "RAW_DELTAT_UDP",
                       Encode(Raw("deltat_udp",
                                  "deltat_83p",
                                  pitmap::raw_bytes_t::TRANSPORT_UDP,
                                  i,
                                  rec.data(),
                                  rec.size())));
        }
        // A protocol without a framer here.
        const std::vector<std::uint8_t> head = {0xFE, 0x44, 0x01};
        WriteEvent(log,
                   2500,
                   "RAW_DELTAT_HEAD",
                   Encode(Raw("deltat_head",
                              "deltat_head",
                              pitmap::raw_bytes_t::TRANSPORT_TCP,
                              0,
                              head.data(),
                              head.size())));
        // Decoded messages and a foreign type.
        pitmap::gnss_position_t pos{};
        for (int i = 0; i < 3; ++i)
            WriteEvent(log, 3000 + i, "GNSS_POSITION_NOVATEL_COM1", Encode(pos));
        WriteEvent(log, 4000, "SOMETHING_ELSE", {1, 2, 3, 4, 5, 6, 7, 8, 9});
    }

    const auto report = InspectFile(tmp.path(), InspectOptions{});
    ASSERT_TRUE(report.ok()) << report.error().message;
    EXPECT_EQ(report->format, InputFormat::kLcmLog);
    ASSERT_EQ(report->sources.size(), 3u);
    const SourceSummary& nov = report->sources[0];
    EXPECT_EQ(nov.protocol, "novatel");
    EXPECT_EQ(nov.bytes, novatel.size());
    EXPECT_EQ(nov.frames_total, 42u);
    EXPECT_EQ(nov.frames_by_id.at("42"), 5u);
    EXPECT_EQ(nov.crc_failures, 0u);
    const SourceSummary& sonar = report->sources[1];
    EXPECT_EQ(sonar.protocol, "deltat_83p");
    EXPECT_EQ(sonar.frames_by_id.at("83P"), 2u);
    EXPECT_EQ(report->sources[2].unframed_bytes, 3u);
    EXPECT_EQ(report->total.frames_total, 44u);

    ASSERT_TRUE(report->lcm);
    const LcmSummary& lcm_summary = *report->lcm;
    EXPECT_EQ(lcm_summary.raw_seq_gaps, 1u);
    EXPECT_EQ(lcm_summary.channels.at("RAW_NOVATEL_COM1").type, "raw_bytes_t");
    EXPECT_EQ(lcm_summary.channels.at("GNSS_POSITION_NOVATEL_COM1").type, "gnss_position_t");
    EXPECT_EQ(lcm_summary.channels.at("GNSS_POSITION_NOVATEL_COM1").events, 3u);
    EXPECT_EQ(lcm_summary.channels.at("SOMETHING_ELSE").type, "unknown");
    const auto json = ToJson(*report);
    EXPECT_EQ(json.at("lcm").at("channels").at("GNSS_POSITION_NOVATEL_COM1").at("type"),
              "gnss_position_t");
    EXPECT_EQ(json.at("frames_by_id").at("83P"), 2);
}

TEST(InspectFileTest, TruncatedLcmLogKeepsTheCompleteEvents) {
    const auto bytes = ReadBytes(kNovatelDir / "oem7drv_time.gps");  // 6 x TIME, 76 bytes each
    TempFile tmp("cut.lcm");
    {
        lcm::LogFile log(tmp.path(), "w");
        for (std::int64_t i = 0; i < 6; ++i) {
            WriteEvent(log,
                       i,
                       "RAW_NOVATEL",
                       Encode(Raw("novatel",
                                  "novatel",
                                  pitmap::raw_bytes_t::TRANSPORT_SERIAL,
                                  i,
                                  bytes.data() + i * 76,
                                  76)));
        }
    }
    auto full = ReadBytes(tmp.path());
    full.resize(full.size() - 40);  // cut inside the last event
    tmp.Write(full);
    const auto report = InspectFile(tmp.path(), InspectOptions{});
    ASSERT_TRUE(report.ok()) << report.error().message;
    ASSERT_TRUE(report->lcm);
    EXPECT_EQ(report->lcm->events, 5u);
    EXPECT_EQ(report->total.frames_by_id.at("101"), 5u);
}

// lcm's own LogFile asserted on a corrupt channel length and allocated what a corrupt data
// length claimed; pitmap-inspect reads with the bounded reader now: a grown data length, a
// raw event whose num_bytes is -5 and a damaged seq are counted, every other event is kept.
TEST(InspectFileTest, DamagedLcmLogIsCountedNotFatal) {
    const auto bytes = ReadBytes(kNovatelDir / "oem7drv_time.gps");  // 6 x TIME, 76 bytes each
    TempFile tmp("damaged.lcm");
    {
        lcm::LogFile log(tmp.path(), "w");
        for (std::int64_t i = 0; i < 6; ++i) {
            WriteEvent(log,
                       i,
                       "RAW_NOVATEL",
                       Encode(Raw("novatel",
                                  "novatel",
                                  pitmap::raw_bytes_t::TRANSPORT_SERIAL,
                                  i,
                                  bytes.data() + i * 76,
                                  76)));
        }
    }
    auto full = ReadBytes(tmp.path());
    const std::size_t event = full.size() / 6;  // every event has the same size
    // Event 1: data length + 9.8 MB. Event 3: num_bytes = -5. Event 4: seq's top byte.
    full[event * 1 + 25] = 0x95;
    const std::size_t num_bytes = event * 4 - 76 - 4;
    for (int k = 0; k < 4; ++k) full[num_bytes + static_cast<std::size_t>(k)] = k < 3 ? 0xFF : 0xFB;
    const std::size_t channel_len = std::string("RAW_NOVATEL").size();
    const std::size_t data4 = event * 4 + 28 + channel_len;
    const std::size_t seq4 = data4 + 8 + 8 + 8 + 1 + (4 + 8) + (4 + 8) + 1;
    full[seq4] = 0x7C;
    tmp.Write(full);
    const auto report = InspectFile(tmp.path(), InspectOptions{});
    ASSERT_TRUE(report.ok()) << report.error().message;
    ASSERT_TRUE(report->lcm);
    EXPECT_EQ(report->lcm->events, 6u);
    EXPECT_EQ(report->lcm->length_repairs, 1u);
    EXPECT_EQ(report->lcm->undecodable_events, 1u);
    EXPECT_EQ(report->lcm->raw_seq_jumps, 1u);
    EXPECT_LE(report->lcm->raw_seq_gaps, 1u);  // event 3's seq is missing from the count
    EXPECT_EQ(report->total.frames_by_id.at("101"), 5u);
}

// ---- Bad inputs ----------------------------------------------------------------------------

TEST(InspectFileTest, BadInputsAreErrorsNamingTheFile) {
    const auto missing = InspectFile("no/such/dir/file.gps", InspectOptions{});
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.error().message.find("no/such/dir/file.gps"), std::string::npos);

    TempFile garbage("garbage.bin");
    std::vector<std::uint8_t> noise(3000);
    for (std::size_t i = 0; i < noise.size(); ++i) {
        noise[i] = static_cast<std::uint8_t>((i * 37 + 11) % 251 % 0x7F);
    }
    garbage.Write(noise);
    const auto unknown = InspectFile(garbage.path(), InspectOptions{});
    ASSERT_FALSE(unknown.ok());
    EXPECT_NE(unknown.error().message.find(garbage.path()), std::string::npos);

    // Forced formats on the wrong bytes: errors or empty reports, never a crash.
    InspectOptions as_pcap;
    as_pcap.format = InputFormat::kPcap;
    EXPECT_FALSE(InspectFile(garbage.path(), as_pcap).ok());
    InspectOptions as_83p;
    as_83p.format = InputFormat::kRaw;
    as_83p.protocol = Protocol::kDeltaT;
    const auto r = InspectFile(garbage.path(), as_83p);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->total.frames_total, 0u);
    EXPECT_EQ(r->total.skipped.TotalBytes(), noise.size());

    // A pcap whose header is cut short.
    TempFile cut("cut.pcap");
    cut.Write({0xD4, 0xC3, 0xB2, 0xA1, 0x02, 0x00, 0x04});
    const auto bad = InspectFile(cut.path(), InspectOptions{});
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.error().message.find(cut.path()), std::string::npos);
}

}  // namespace
}  // namespace pitmap::tools::inspect
