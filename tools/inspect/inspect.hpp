// SPDX-License-Identifier: MIT
// pitmap-inspect's logic: what is in a raw NovAtel byte file, a .83P file, a packet capture or a
// pitmap LCM log, frame by frame.
//
// Every byte source in the input is framed with the framer of its protocol, exactly once:
//   raw file      one source (NovAtel or Delta T 83P, chosen by --protocol or detected);
//   pcap/pcapng   one source per TCP direction that carries bytes (reassembled) and per UDP
//                 flow (datagrams framed one by one);
//   LCM log       one source per raw_bytes_t (channel, source) pair, framed by its `protocol`;
//                 decoded channels are counted by channel and type, not framed.
// The summary counts frames by message id, CRC failures, skipped bytes by reason, the bytes cut
// off at the end, and the span of the sensor's own time stamps.
//
// Failure: an input that cannot be read or whose kind cannot be told is an Error naming the
// file. Bad bytes inside a readable input are counted, never fatal.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/byte_io.hpp"
#include "common/protocol/framing.hpp"
#include "common/result.hpp"

namespace pitmap::tools::inspect {

enum class InputFormat : std::uint8_t { kAuto = 0, kRaw, kPcap, kLcmLog };
enum class Protocol : std::uint8_t { kAuto = 0, kNovatel, kDeltaT };

std::string ToString(InputFormat format);  // "auto", "raw", "pcap", "lcm"
std::string ToString(Protocol protocol);   // "auto", "novatel", "deltat_83p"
// Parses the command-line spellings: raw|pcap|lcm|83p (83p = raw + Delta T), novatel|deltat.
std::optional<InputFormat> ParseInputFormat(const std::string& text);
std::optional<Protocol> ParseProtocol(const std::string& text);

struct InspectOptions {
    InputFormat format = InputFormat::kAuto;
    Protocol protocol = Protocol::kAuto;  // for raw files and capture streams
    std::size_t chunk_bytes = 4096;       // raw files are pushed to the framer in such blocks
    // Decoded fields of the first N (and the last) messages of each sampled type (BESTPOS,
    // BESTVEL, INSPVA(S), INSPVAX, INSATTX, HEADING2, TIME) go into the report; 0 = none.
    std::size_t dump_first = 0;
};

// Decoded fields of some messages of one type (SI units as the decoder gives them, angles in
// degrees as NovAtel sends them).
struct DecodedSamples {
    std::uint64_t count = 0;            // messages of this type decoded
    std::vector<nlohmann::json> first;  // the first dump_first of them
    nlohmann::json last;                // the last one (null if count <= dump_first)
};

// What detection concluded about a file's first bytes and name.
struct Detected {
    InputFormat format = InputFormat::kRaw;
    Protocol protocol = Protocol::kNovatel;  // meaningful for kRaw
};

// Tells the kind of an input from its (decompressed) bytes and its name: pcap/pcapng magic,
// LCM log sync word 0xEDA1DA01, a leading `83P` marker or a .83P name (Delta T), NovAtel sync
// patterns in the first 64 KiB (AA 44 12, AA 44 13, AA 45 12, "#", "%", "<OK", "[COM"...).
// Error (naming `name`) when none of these match.
Expected<Detected> DetectFormat(ByteSpan bytes, const std::string& name);

// Frame counts of one byte source (or of all of them added up).
struct SourceSummary {
    std::string name;          // "file", "192.168.0.2:3001 > 192.168.0.1:50000", LCM channel/source
    std::string protocol;      // "novatel", "deltat_83p", or what an LCM raw channel said
    std::uint64_t bytes = 0;   // bytes fed to the framer
    std::uint64_t chunks = 0;  // Push calls (raw_bytes_t events, TCP deliveries, datagrams)
    std::uint64_t frames_total = 0;
    std::uint64_t log_frames = 0;  // binary/ASCII/NMEA logs and 83P pings (not responses)
    std::uint64_t responses = 0;   // command responses: binary/ASCII with the response flag,
                                   // <OK and <ERROR lines
    std::uint64_t prompts = 0;     // [COM1], [ICOM1], ...
    // "42" (binary id), "1R" (binary response to command 1), "#RXSTATUSEVENTA", "%INSPVASA",
    // "OK", "ERROR", "<BESTPOS" (abbreviated log), "PROMPT", "$GPGGA", "83P", "83P_COMMENT",
    // "P1234" (proprietary AA 45 12 frame).
    std::map<std::string, std::uint64_t> frames_by_id;
    std::map<std::string, std::uint64_t> frames_by_kind;  // "long_binary", "prompt", "83p", ...
    std::uint64_t crc_failures = 0;                       // Skipped events with reason bad_crc
    protocol::SkipCounters skipped;                       // bytes and events by reason
    std::uint64_t truncated_tail_bytes = 0;  // what Flush() gave up at the end of the source
    std::uint64_t unframed_bytes = 0;        // bytes of a protocol no framer here knows
    std::uint64_t datagram_errors = 0;       // UDP 83P datagrams that did not decode
    // NovAtel decoder results (common/protocol/novatel/decoder.hpp) for every frame.
    std::uint64_t decoded = 0;      // frames that decoded to a message
    std::uint64_t unsupported = 0;  // valid frames without a decoder (counted, not an error)
    std::map<std::string, std::uint64_t> decode_errors;  // by DecodeErrorKind name
    std::map<std::string, DecodedSamples> samples;       // by message name, if dump_first > 0
    // GPS time from NovAtel headers (week 0 = unknown time is left out), as GPS seconds since
    // 1980-01-06 (week * 604800 + seconds of week).
    std::optional<double> gps_start_s;
    std::optional<double> gps_end_s;
    // 83P header clock (Unix microseconds, as the sonar's clock says).
    std::optional<std::int64_t> sonar_start_utime;
    std::optional<std::int64_t> sonar_end_utime;

    void Add(const SourceSummary& other);  // adds counts, widens time spans
};

struct TcpSummary {
    std::string name;
    std::uint64_t bytes = 0;
    std::uint64_t packets = 0;
    std::uint64_t payload_segments = 0;
    std::uint64_t retransmitted_segments = 0;
    std::uint64_t retransmitted_bytes = 0;
    std::uint64_t out_of_order_segments = 0;
    std::uint64_t gaps = 0;
    std::uint64_t gap_bytes = 0;
};

struct CaptureSummary {
    std::string format;  // pcap, pcapng
    bool gzip = false;
    std::string link_type;
    std::uint64_t packets = 0;
    std::uint64_t tcp_packets = 0;
    std::uint64_t udp_packets = 0;
    std::uint64_t other_packets = 0;      // non-IP, other IP protocols, fragments
    std::uint64_t truncated_packets = 0;  // damaged headers + payloads cut by the snap length
    std::int64_t first_utime = 0;
    std::int64_t last_utime = 0;
    std::string read_error;
    std::vector<TcpSummary> tcp;
    std::uint64_t udp_datagrams = 0;
};

struct LcmChannelSummary {
    std::string type;  // lcmtype name from the fingerprint, "raw_bytes_t", or "unknown"
    std::uint64_t events = 0;
    std::uint64_t bytes = 0;
};

struct LcmSummary {
    std::uint64_t events = 0;
    std::int64_t first_utime = 0;  // log event timestamps, Unix microseconds
    std::int64_t last_utime = 0;
    std::map<std::string, LcmChannelSummary> channels;
    std::uint64_t raw_seq_gaps = 0;   // raw_bytes_t chunks missing according to `seq`
    std::uint64_t raw_seq_jumps = 0;  // implausible jumps of `seq` (damaged or reset counter)
    // Damage found by the bounded log reader (lcmtypes/log/lcm_log_reader.hpp).
    std::uint64_t corrupt_headers = 0;
    std::uint64_t resync_bytes = 0;
    std::uint64_t length_repairs = 0;
    std::uint64_t truncated_bytes = 0;     // a last event cut by the end of the file
    std::uint64_t undecodable_events = 0;  // raw_bytes_t events that fail the wire check
};

struct InspectReport {
    std::string file;  // the file name as given on the command line
    InputFormat format = InputFormat::kRaw;
    std::uint64_t input_bytes = 0;  // after decompression
    SourceSummary total;            // all sources added up
    std::vector<SourceSummary> sources;
    std::optional<CaptureSummary> capture;
    std::optional<LcmSummary> lcm;
};

// Reads and summarises one input file.
Expected<InspectReport> InspectFile(const std::string& path, const InspectOptions& options);

// Frames a byte stream already in memory as one source (used for raw files; exposed for tests).
SourceSummary InspectStream(ByteSpan bytes,
                            Protocol protocol,
                            const InspectOptions& options,
                            const std::string& name);

// The machine-readable report: ONE object. Keys at the top level: file (base name only, so
// golden files do not depend on where the data lives), format, input_bytes, frames_total,
// log_frames, responses, prompts, frames_by_id, frames_by_kind, message_names, crc_failures,
// skipped_bytes {total, <reason>...}, truncated_tail_bytes, time_span, decoded, unsupported,
// decode_errors, samples (when dump_first > 0), sources[], and capture or lcm when the input
// was one.
nlohmann::json ToJson(const InspectReport& report);

// The human-readable report.
std::string ToText(const InspectReport& report);

}  // namespace pitmap::tools::inspect
