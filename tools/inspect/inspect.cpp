// SPDX-License-Identifier: MIT
#include "tools/inspect/inspect.hpp"

#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string_view>
#include <utility>
#include <variant>

#include "common/capture/capture.hpp"
#include "common/protocol/deltat/stream_framer.hpp"
#include "common/protocol/novatel/decoder.hpp"
#include "common/protocol/novatel/framer.hpp"
#include "lcmtypes/log/channels.hpp"
#include "lcmtypes/log/lcm_log_reader.hpp"
#include "lcmtypes/log/lcm_wire.hpp"
#include "pitmap/channel_status_t.hpp"
#include "pitmap/clock_sync_t.hpp"
#include "pitmap/daemon_status_t.hpp"
#include "pitmap/gnss_position_t.hpp"
#include "pitmap/gnss_velocity_t.hpp"
#include "pitmap/gps_time_t.hpp"
#include "pitmap/heading_t.hpp"
#include "pitmap/imu_t.hpp"
#include "pitmap/ins_attitude_t.hpp"
#include "pitmap/ins_pva_t.hpp"
#include "pitmap/ins_stddev_t.hpp"
#include "pitmap/mark_time_t.hpp"
#include "pitmap/multibeam_ping_t.hpp"
#include "pitmap/novatel_header_t.hpp"
#include "pitmap/raw_bytes_t.hpp"
#include "pitmap/receiver_response_t.hpp"

namespace pitmap::tools::inspect {
namespace {

namespace novatel = protocol::novatel;
namespace deltat = protocol::deltat;

constexpr double kSecondsPerWeek = 604800.0;
constexpr std::size_t kSniffBytes = 64 * 1024;

void WidenGps(SourceSummary& s, double t) {
    s.gps_start_s = s.gps_start_s ? std::min(*s.gps_start_s, t) : t;
    s.gps_end_s = s.gps_end_s ? std::max(*s.gps_end_s, t) : t;
}

void WidenSonar(SourceSummary& s, std::int64_t t) {
    s.sonar_start_utime = s.sonar_start_utime ? std::min(*s.sonar_start_utime, t) : t;
    s.sonar_end_utime = s.sonar_end_utime ? std::max(*s.sonar_end_utime, t) : t;
}

std::string_view AsText(ByteSpan bytes) {
    return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

// Comma-separated header fields of an ASCII frame, up to the ';' that ends the header.
std::vector<std::string_view> HeaderFields(std::string_view text) {
    const std::size_t end = std::min(text.find(';'), text.find('*'));
    text = text.substr(0, end);
    std::vector<std::string_view> fields;
    std::size_t start = 0;
    while (true) {
        const std::size_t comma = text.find(',', start);
        fields.push_back(text.substr(start, comma - start));
        if (comma == std::string_view::npos) break;
        start = comma + 1;
    }
    return fields;
}

// GPS seconds from ASCII week and seconds-of-week fields; nullopt for week 0 or non-numbers.
std::optional<double> AsciiGpsTime(std::string_view week_text, std::string_view sow_text) {
    const std::string week_str(week_text);
    const std::string sow_str(sow_text);
    char* end = nullptr;
    const long week = std::strtol(week_str.c_str(), &end, 10);
    if (week_str.empty() || *end != '\0' || week <= 0) return std::nullopt;
    const double sow = std::strtod(sow_str.c_str(), &end);
    if (sow_str.empty() || *end != '\0' || sow < 0.0 || sow >= kSecondsPerWeek) {
        return std::nullopt;
    }
    return static_cast<double>(week) * kSecondsPerWeek + sow;
}

void CountKey(SourceSummary& s, const std::string& key) {
    ++s.frames_by_id[key];
}

// One NovAtel frame into the summary (spec §2, §3, §5 for the header fields read here).
void CountNovatelFrame(const novatel::Frame& frame, SourceSummary& s) {
    ++s.frames_total;
    ++s.frames_by_kind[std::string(novatel::ToString(frame.kind))];
    const ByteSpan b = frame.bytes;
    switch (frame.kind) {
        case novatel::FrameKind::kLongBinary: {
            ByteReader r(b);
            r.Seek(6);
            const bool response = (r.U8() & 0x80) != 0;  // message type bit 7
            r.Seek(14);
            const std::uint16_t week = r.U16Le();
            const std::uint32_t ms = r.U32Le();
            CountKey(s, std::to_string(frame.message_id) + (response ? "R" : ""));
            if (response) {
                ++s.responses;
            } else {
                ++s.log_frames;
            }
            if (r.ok() && week != 0) {
                WidenGps(s, week * kSecondsPerWeek + static_cast<double>(ms) / 1000.0);
            }
            break;
        }
        case novatel::FrameKind::kShortBinary: {
            ByteReader r(b);
            r.Seek(6);
            const std::uint16_t week = r.U16Le();
            const std::uint32_t ms = r.U32Le();
            CountKey(s, std::to_string(frame.message_id));
            ++s.log_frames;
            if (r.ok() && week != 0) {
                WidenGps(s, week * kSecondsPerWeek + static_cast<double>(ms) / 1000.0);
            }
            break;
        }
        case novatel::FrameKind::kProprietary:
            CountKey(s, "P" + std::to_string(frame.message_id));
            ++s.log_frames;
            break;
        case novatel::FrameKind::kAscii: {
            const auto fields = HeaderFields(AsText(b.subspan(1)));
            const std::string name(fields.front());
            CountKey(s, "#" + name);
            if (!name.empty() && name.back() == 'R') {
                ++s.responses;
            } else {
                ++s.log_frames;
            }
            if (fields.size() > 6) {
                if (auto t = AsciiGpsTime(fields[5], fields[6])) WidenGps(s, *t);
            }
            break;
        }
        case novatel::FrameKind::kShortAscii: {
            const auto fields = HeaderFields(AsText(b.subspan(1)));
            CountKey(s, "%" + std::string(fields.front()));
            ++s.log_frames;
            if (fields.size() > 2) {
                if (auto t = AsciiGpsTime(fields[1], fields[2])) WidenGps(s, *t);
            }
            break;
        }
        case novatel::FrameKind::kAbbreviated: {
            std::string_view text = AsText(b.subspan(1));
            while (!text.empty() && (text.back() == '\r' || text.back() == '\n')) {
                text.remove_suffix(1);
            }
            if (text.substr(0, 2) == "OK") {
                CountKey(s, "OK");
                ++s.responses;
            } else if (text.substr(0, 5) == "ERROR") {
                CountKey(s, "ERROR");
                ++s.responses;
            } else {
                const std::size_t space = text.find(' ');
                CountKey(s, "<" + std::string(text.substr(0, space)));
                ++s.log_frames;
            }
            break;
        }
        case novatel::FrameKind::kPrompt:
            CountKey(s, "PROMPT");
            ++s.prompts;
            break;
        case novatel::FrameKind::kNmea: {
            std::string_view text = AsText(b);
            CountKey(s, std::string(text.substr(0, std::min(text.find(','), text.find('*')))));
            ++s.log_frames;
            break;
        }
    }
}

// Rounded so that golden files hold what the decoder means, not the last bit of a double.
double Round(double v, double quantum) {
    return std::round(v / quantum) * quantum;
}
double Deg(double v) {
    return Round(v, 1e-9);
}
double Metres(double v) {
    return Round(v, 1e-4);
}
double Small(double v) {
    return Round(v, 1e-6);
}

nlohmann::json HeaderTime(const novatel::Header& h) {
    return nlohmann::json{{"gps_week", h.gps_week}, {"gps_ms", h.gps_ms}};
}

// The sampled fields of a decoded message, with its name; nullopt for types not sampled.
std::optional<std::pair<std::string, nlohmann::json>> Sample(const novatel::DecodeResult& r) {
    using nlohmann::json;
    if (const auto* m = std::get_if<novatel::BestPos>(&r)) {
        return std::pair{std::string("BESTPOS"),
                         json{{"time", HeaderTime(m->header)},
                              {"solution_status", static_cast<std::uint32_t>(m->solution_status)},
                              {"position_type", static_cast<std::uint32_t>(m->position_type)},
                              {"latitude_deg", Deg(m->latitude_deg)},
                              {"longitude_deg", Deg(m->longitude_deg)},
                              {"height_msl_m", Metres(m->height_msl_m)},
                              {"undulation_m", Metres(m->undulation_m)},
                              {"num_svs_in_solution", m->num_svs_in_solution}}};
    }
    if (const auto* m = std::get_if<novatel::BestVel>(&r)) {
        return std::pair{std::string("BESTVEL"),
                         json{{"time", HeaderTime(m->header)},
                              {"horizontal_speed_mps", Small(m->horizontal_speed_mps)},
                              {"track_over_ground_deg", Small(m->track_over_ground_deg)},
                              {"vertical_speed_mps", Small(m->vertical_speed_mps)}}};
    }
    if (const auto* m = std::get_if<novatel::InsPva>(&r)) {
        return std::pair{std::string("INSPVA"),
                         json{{"gps_week", m->gps_week},
                              {"gps_seconds", Small(m->gps_seconds)},
                              {"latitude_deg", Deg(m->latitude_deg)},
                              {"longitude_deg", Deg(m->longitude_deg)},
                              {"height_ellipsoid_m", Metres(m->height_ellipsoid_m)},
                              {"roll_deg", Small(m->roll_deg)},
                              {"pitch_deg", Small(m->pitch_deg)},
                              {"azimuth_deg", Small(m->azimuth_deg)},
                              {"ins_status", static_cast<std::uint32_t>(m->ins_status)}}};
    }
    if (const auto* m = std::get_if<novatel::InsPvaX>(&r)) {
        return std::pair{std::string("INSPVAX"),
                         json{{"time", HeaderTime(m->header)},
                              {"latitude_deg", Deg(m->latitude_deg)},
                              {"longitude_deg", Deg(m->longitude_deg)},
                              {"height_msl_m", Metres(m->height_msl_m)},
                              {"roll_deg", Small(m->roll_deg)},
                              {"pitch_deg", Small(m->pitch_deg)},
                              {"azimuth_deg", Small(m->azimuth_deg)},
                              {"ins_status", static_cast<std::uint32_t>(m->ins_status)}}};
    }
    if (const auto* m = std::get_if<novatel::InsAttX>(&r)) {
        return std::pair{std::string("INSATTX"),
                         json{{"time", HeaderTime(m->header)},
                              {"roll_deg", Small(m->roll_deg)},
                              {"pitch_deg", Small(m->pitch_deg)},
                              {"azimuth_deg", Small(m->azimuth_deg)}}};
    }
    if (const auto* m = std::get_if<novatel::Heading2>(&r)) {
        return std::pair{std::string("HEADING2"),
                         json{{"time", HeaderTime(m->header)},
                              {"heading_deg", Small(m->heading_deg)},
                              {"pitch_deg", Small(m->pitch_deg)},
                              {"baseline_length_m", Metres(m->baseline_length_m)}}};
    }
    if (const auto* m = std::get_if<novatel::Time>(&r)) {
        return std::pair{std::string("TIME"),
                         json{{"time", HeaderTime(m->header)},
                              {"utc_offset_s", Small(m->utc_offset_s)},
                              {"utc_year", m->utc_year},
                              {"utc_month", m->utc_month},
                              {"utc_day", m->utc_day}}};
    }
    return std::nullopt;
}

void CountDecoded(const novatel::Frame& frame, std::size_t dump_first, SourceSummary& s) {
    const auto result = novatel::Decode(frame);
    if (const auto* error = std::get_if<novatel::DecodeError>(&result)) {
        ++s.decode_errors[std::string(novatel::ToString(error->kind))];
        return;
    }
    if (std::holds_alternative<novatel::Unsupported>(result)) {
        ++s.unsupported;
        return;
    }
    ++s.decoded;
    if (dump_first == 0) return;
    auto sample = Sample(result);
    if (!sample) return;
    auto& samples = s.samples[sample->first];
    ++samples.count;
    if (samples.first.size() < dump_first) {
        samples.first.push_back(std::move(sample->second));
    } else {
        samples.last = std::move(sample->second);
    }
}

void CountSkipped(const protocol::Skipped& skipped, SourceSummary& s) {
    s.skipped.Add(skipped);
    if (skipped.reason == protocol::SkipReason::kBadCrc) ++s.crc_failures;
}

protocol::SkipReason ReasonFor(deltat::DecodeErrorKind kind) {
    switch (kind) {
        case deltat::DecodeErrorKind::kTruncated:
            return protocol::SkipReason::kTruncated;
        case deltat::DecodeErrorKind::kBadMarker:
        case deltat::DecodeErrorKind::kUnsupported:
            return protocol::SkipReason::kGarbage;
        case deltat::DecodeErrorKind::kBadTerminator:
            return protocol::SkipReason::kBadTerminator;
        default:
            return protocol::SkipReason::kBadLength;
    }
}

// Frames one byte source with the framer of its protocol and counts what comes out.
class SourceCounter {
public:
    enum class Mode : std::uint8_t { kNovatel, kDeltaTStream, kDeltaTDatagram, kUnframed };

    SourceCounter(std::string name, std::string protocol_name, Mode mode, std::size_t dump_first)
        : mode_(mode), dump_first_(dump_first) {
        summary_.name = std::move(name);
        summary_.protocol = std::move(protocol_name);
        if (mode_ == Mode::kNovatel) novatel_ = std::make_unique<novatel::Framer>();
        if (mode_ == Mode::kDeltaTStream) deltat_ = std::make_unique<deltat::StreamFramer>();
    }

    // One chunk as the transport delivered it (a UDP datagram in datagram mode).
    void Push(ByteSpan bytes) {
        summary_.bytes += bytes.size();
        ++summary_.chunks;
        switch (mode_) {
            case Mode::kNovatel:
                novatel_->Push(bytes);
                DrainNovatel();
                break;
            case Mode::kDeltaTStream:
                deltat_->Push(bytes);
                DrainDeltaT();
                break;
            case Mode::kDeltaTDatagram:
                CountDatagram(bytes);
                break;
            case Mode::kUnframed:
                summary_.unframed_bytes += bytes.size();
                break;
        }
    }

    // The stream breaks (bytes missing from a capture): a frame cannot span the break.
    void Break() { GiveUpPartials(false); }

    SourceSummary Finish() {
        GiveUpPartials(true);
        return std::move(summary_);
    }

private:
    // The candidate waiting for more bytes gives up its sync only; the bytes it held are framed
    // again, until nothing is buffered (frames behind a false header are found).
    void GiveUpPartials(bool end_of_source) {
        while (novatel_) {
            const auto tail = novatel_->Flush();
            if (!tail) break;
            CountSkipped(*tail, summary_);
            if (end_of_source) summary_.truncated_tail_bytes += tail->bytes;
            DrainNovatel();
        }
        while (deltat_) {
            const auto tail = deltat_->Flush();
            if (!tail) break;
            CountSkipped(*tail, summary_);
            if (end_of_source) summary_.truncated_tail_bytes += tail->bytes;
            DrainDeltaT();
        }
    }

    void DrainNovatel() {
        while (true) {
            auto ev = novatel_->Next();
            if (std::holds_alternative<protocol::NeedMore>(ev)) break;
            if (const auto* skipped = std::get_if<protocol::Skipped>(&ev)) {
                CountSkipped(*skipped, summary_);
                continue;
            }
            const auto& frame = std::get<novatel::Frame>(ev);
            CountNovatelFrame(frame, summary_);
            CountDecoded(frame, dump_first_, summary_);
        }
    }

    void DrainDeltaT() {
        while (true) {
            auto ev = deltat_->Next();
            if (std::holds_alternative<protocol::NeedMore>(ev)) break;
            if (const auto* skipped = std::get_if<protocol::Skipped>(&ev)) {
                CountSkipped(*skipped, summary_);
                continue;
            }
            const auto& record = std::get<deltat::Record>(ev);
            ++summary_.frames_total;
            ++summary_.frames_by_kind["83p"];
            const auto decoded = deltat::DecodeRecord83PInto(record.bytes, memory_, ping_);
            CountDecoded83P(decoded);
        }
    }

    void CountDatagram(ByteSpan datagram) {
        const auto decoded = deltat::DecodeDatagramInto(datagram, memory_, ping_);
        if (const auto* error = std::get_if<deltat::DecodeError>(&decoded)) {
            ++summary_.datagram_errors;
            CountSkipped(
                protocol::Skipped{
                    ReasonFor(error->kind), datagram.size(), summary_.bytes - datagram.size()},
                summary_);
            return;
        }
        ++summary_.frames_total;
        ++summary_.frames_by_kind["83p"];
        CountDecoded83P(decoded);
    }

    void CountDecoded83P(const std::variant<deltat::RecordKind, deltat::DecodeError>& decoded) {
        if (const auto* kind = std::get_if<deltat::RecordKind>(&decoded)) {
            if (*kind == deltat::RecordKind::kComment) {
                CountKey(summary_, "83P_COMMENT");
                return;
            }
            CountKey(summary_, "83P");
            ++summary_.log_frames;
            if (ping_.utime_sonar_header != 0) WidenSonar(summary_, ping_.utime_sonar_header);
            return;
        }
        // Framed (the header validated) but the body did not decode.
        CountKey(summary_, "83P_UNDECODED");
        ++summary_.log_frames;
    }

    Mode mode_;
    std::size_t dump_first_ = 0;
    SourceSummary summary_;
    std::unique_ptr<novatel::Framer> novatel_;
    std::unique_ptr<deltat::StreamFramer> deltat_;
    deltat::FloatOrderMemory memory_;
    deltat::Ping83P ping_;
};

bool StartsWith(ByteSpan bytes, std::string_view prefix) {
    return bytes.size() >= prefix.size() && AsText(bytes.first(prefix.size())) == prefix;
}

bool EndsWithNoCase(const std::string& text, std::string_view suffix) {
    if (text.size() < suffix.size()) return false;
    for (std::size_t i = 0; i < suffix.size(); ++i) {
        const char a = text[text.size() - suffix.size() + i];
        if (std::tolower(static_cast<unsigned char>(a)) !=
            std::tolower(static_cast<unsigned char>(suffix[i]))) {
            return false;
        }
    }
    return true;
}

bool LooksLikeNovatel(ByteSpan bytes) {
    const ByteSpan head = bytes.first(std::min(bytes.size(), kSniffBytes));
    const std::string_view text = AsText(head);
    for (std::size_t i = 0; i + 2 < head.size(); ++i) {
        if (head[i] == 0xAA && (head[i + 1] == 0x44 || head[i + 1] == 0x45) &&
            (head[i + 2] == 0x12 || head[i + 2] == 0x13)) {
            return true;
        }
    }
    for (std::string_view marker :
         {"<OK", "<ERROR", "[COM", "[ICOM", "[USB", "[NCOM", "$GP", "$GN"}) {
        if (text.find(marker) != std::string_view::npos) return true;
    }
    // An ASCII log header: '#' or '%', an upper-case name, then ','.
    for (std::size_t i = 0; i + 2 < text.size(); ++i) {
        if (text[i] != '#' && text[i] != '%') continue;
        std::size_t j = i + 1;
        while (j < text.size() && std::isupper(static_cast<unsigned char>(text[j]))) ++j;
        if (j > i + 3 && j < text.size() && text[j] == ',') return true;
    }
    return false;
}

bool LooksLikeDeltaT(ByteSpan bytes, const std::string& name) {
    return StartsWith(bytes, "83P") || EndsWithNoCase(name, ".83p");
}

std::string LcmTypeName(ByteSpan data) {
    if (data.size() < 8) return "unknown";
    const auto hash = static_cast<std::int64_t>(ByteReader(data.data(), 8).U64Be());
    struct Known {
        std::int64_t hash;
        const char* name;
    };
    static const Known kKnown[] = {
        {pitmap::channel_status_t::getHash(), "channel_status_t"},
        {pitmap::clock_sync_t::getHash(), "clock_sync_t"},
        {pitmap::daemon_status_t::getHash(), "daemon_status_t"},
        {pitmap::gnss_position_t::getHash(), "gnss_position_t"},
        {pitmap::gnss_velocity_t::getHash(), "gnss_velocity_t"},
        {pitmap::gps_time_t::getHash(), "gps_time_t"},
        {pitmap::heading_t::getHash(), "heading_t"},
        {pitmap::imu_t::getHash(), "imu_t"},
        {pitmap::ins_attitude_t::getHash(), "ins_attitude_t"},
        {pitmap::ins_pva_t::getHash(), "ins_pva_t"},
        {pitmap::ins_stddev_t::getHash(), "ins_stddev_t"},
        {pitmap::mark_time_t::getHash(), "mark_time_t"},
        {pitmap::multibeam_ping_t::getHash(), "multibeam_ping_t"},
        {pitmap::novatel_header_t::getHash(), "novatel_header_t"},
        {pitmap::raw_bytes_t::getHash(), "raw_bytes_t"},
        {pitmap::receiver_response_t::getHash(), "receiver_response_t"},
    };
    for (const auto& k : kKnown) {
        if (k.hash == hash) return k.name;
    }
    return "unknown";
}

SourceCounter::Mode ModeForRawProtocol(const std::string& protocol_name, std::int8_t transport) {
    if (protocol_name == lcmlog::kProtocolNovatel) return SourceCounter::Mode::kNovatel;
    if (protocol_name == lcmlog::kProtocolDeltat83P) {
        return transport == pitmap::raw_bytes_t::TRANSPORT_UDP
                   ? SourceCounter::Mode::kDeltaTDatagram
                   : SourceCounter::Mode::kDeltaTStream;
    }
    return SourceCounter::Mode::kUnframed;
}

// Raw chunks a daemon writes in a day at 1 kHz is 8.6e7; more than that between two chunks of
// one source is a damaged or reset counter.
constexpr std::int64_t kMaxPlausibleSeqGap = 100'000'000;

Expected<InspectReport> InspectLcmLog(const std::string& path,
                                      const InspectOptions& options,
                                      InspectReport report) {
    // The bounded reader: a corrupted length resynchronises instead of asserting or
    // allocating what it claims, and every message is bounds-checked before it is decoded.
    auto log = lcmlog::LcmLogReader::Open(path);
    if (!log) return log.error();
    LcmSummary lcm_summary;
    // Sources in order of first appearance, keyed by channel and source id.
    std::vector<std::unique_ptr<SourceCounter>> counters;
    std::map<std::string, std::size_t> index;
    std::map<std::string, std::int64_t> last_seq;
    pitmap::raw_bytes_t raw;
    lcmlog::LcmEvent ev;
    while ((*log)->Next(ev)) {
        ++lcm_summary.events;
        if (lcm_summary.events == 1) lcm_summary.first_utime = ev.utime;
        lcm_summary.last_utime = ev.utime;
        auto& channel = lcm_summary.channels[std::string(ev.channel)];
        ++channel.events;
        channel.bytes += ev.data.size();
        const std::string type = LcmTypeName(ev.data);
        if (type == "raw_bytes_t") {
            if (!lcmlog::DecodeChecked(raw, ev.data.data(), ev.data.size())) {
                channel.type = type;
                ++lcm_summary.undecodable_events;
                continue;
            }
            channel.type = "raw_bytes_t";
            const std::string key = std::string(ev.channel) + " " + raw.source;
            auto it = index.find(key);
            if (it == index.end()) {
                counters.push_back(
                    std::make_unique<SourceCounter>(key,
                                                    raw.protocol,
                                                    ModeForRawProtocol(raw.protocol, raw.transport),
                                                    options.dump_first));
                it = index.emplace(key, counters.size() - 1).first;
            } else if (raw.seq > last_seq[key] + 1) {
                // A gap larger than any log could hold is a damaged counter, not lost chunks.
                const std::int64_t gap = raw.seq - last_seq[key] - 1;
                if (gap <= kMaxPlausibleSeqGap) {
                    lcm_summary.raw_seq_gaps += static_cast<std::uint64_t>(gap);
                } else {
                    ++lcm_summary.raw_seq_jumps;
                }
            }
            last_seq[key] = raw.seq;
            counters[it->second]->Push(ByteSpan(raw.data.data(), raw.data.size()));
            continue;
        }
        channel.type = type;
    }
    const lcmlog::LcmLogCounts& lc = (*log)->counts();
    lcm_summary.corrupt_headers = static_cast<std::uint64_t>(lc.corrupt_headers);
    lcm_summary.resync_bytes = static_cast<std::uint64_t>(lc.resync_bytes);
    lcm_summary.length_repairs = static_cast<std::uint64_t>(lc.length_repairs);
    lcm_summary.truncated_bytes = static_cast<std::uint64_t>(lc.truncated_bytes);
    for (auto& counter : counters) {
        report.sources.push_back(counter->Finish());
        report.total.Add(report.sources.back());
    }
    report.lcm = std::move(lcm_summary);
    return report;
}

SourceCounter::Mode StreamMode(Protocol protocol, ByteSpan first_bytes) {
    if (protocol == Protocol::kDeltaT) return SourceCounter::Mode::kDeltaTStream;
    if (protocol == Protocol::kNovatel) return SourceCounter::Mode::kNovatel;
    return StartsWith(first_bytes, "83P") ? SourceCounter::Mode::kDeltaTStream
                                          : SourceCounter::Mode::kNovatel;
}

std::string ModeName(SourceCounter::Mode mode) {
    return std::string(mode == SourceCounter::Mode::kNovatel ? lcmlog::kProtocolNovatel
                                                             : lcmlog::kProtocolDeltat83P);
}

InspectReport InspectCapture(capture::CaptureContents contents,
                             const InspectOptions& options,
                             InspectReport report) {
    CaptureSummary cap;
    const auto& st = contents.stats;
    cap.format = st.format;
    cap.gzip = st.gzip;
    cap.link_type = st.link_type_name;
    cap.packets = st.packets;
    cap.tcp_packets = st.tcp_packets;
    cap.udp_packets = st.udp_packets;
    cap.other_packets = st.non_ip_packets + st.other_ip_packets + st.ip_fragments;
    cap.truncated_packets = st.truncated_packets + st.truncated_payloads;
    cap.first_utime = st.first_utime;
    cap.last_utime = st.last_utime;
    cap.read_error = st.read_error;
    cap.udp_datagrams = contents.udp.size();

    for (const auto& stream : contents.tcp) {
        const std::string name = stream.src.ToString() + " > " + stream.dst.ToString();
        TcpSummary t;
        t.name = name;
        t.bytes = stream.bytes.size();
        t.packets = stream.stats.packets;
        t.payload_segments = stream.stats.payload_segments;
        t.retransmitted_segments = stream.stats.retransmitted_segments;
        t.retransmitted_bytes = stream.stats.retransmitted_bytes;
        t.out_of_order_segments = stream.stats.out_of_order_segments;
        t.gaps = stream.stats.gaps;
        t.gap_bytes = stream.stats.gap_bytes;
        cap.tcp.push_back(t);
        if (stream.bytes.empty()) continue;  // the direction that only acknowledges

        const ByteSpan all(stream.bytes);
        const auto mode = StreamMode(options.protocol, all);
        SourceCounter counter("tcp " + name, ModeName(mode), mode, options.dump_first);
        // Feed the bytes as the socket delivered them; break the stream at capture gaps.
        std::size_t gap_index = 0;
        for (std::size_t i = 0; i < stream.chunks.size(); ++i) {
            const std::size_t begin = stream.chunks[i].offset;
            const std::size_t end =
                i + 1 < stream.chunks.size() ? stream.chunks[i + 1].offset : all.size();
            while (gap_index < stream.gaps.size() && stream.gaps[gap_index].offset <= begin) {
                if (stream.gaps[gap_index].offset == begin && begin != 0) counter.Break();
                ++gap_index;
            }
            counter.Push(all.subspan(begin, end - begin));
        }
        report.sources.push_back(counter.Finish());
    }

    // UDP: one source per flow, one Push per datagram.
    std::vector<std::unique_ptr<SourceCounter>> udp_counters;
    std::map<std::string, std::size_t> udp_index;
    for (const auto& dgram : contents.udp) {
        const std::string name = "udp " + dgram.src.ToString() + " > " + dgram.dst.ToString();
        auto it = udp_index.find(name);
        if (it == udp_index.end()) {
            auto mode = StreamMode(options.protocol, dgram.payload);
            if (mode == SourceCounter::Mode::kDeltaTStream) {
                mode = SourceCounter::Mode::kDeltaTDatagram;  // one record per datagram (§3.2)
            }
            udp_counters.push_back(
                std::make_unique<SourceCounter>(name, ModeName(mode), mode, options.dump_first));
            it = udp_index.emplace(name, udp_counters.size() - 1).first;
        }
        udp_counters[it->second]->Push(dgram.payload);
    }
    for (auto& counter : udp_counters) report.sources.push_back(counter->Finish());

    for (const auto& source : report.sources) report.total.Add(source);
    report.capture = std::move(cap);
    return report;
}

}  // namespace

std::string ToString(InputFormat format) {
    switch (format) {
        case InputFormat::kAuto:
            return "auto";
        case InputFormat::kRaw:
            return "raw";
        case InputFormat::kPcap:
            return "pcap";
        case InputFormat::kLcmLog:
            return "lcm";
    }
    return "unknown";
}

std::string ToString(Protocol protocol) {
    switch (protocol) {
        case Protocol::kAuto:
            return "auto";
        case Protocol::kNovatel:
            return std::string(lcmlog::kProtocolNovatel);
        case Protocol::kDeltaT:
            return std::string(lcmlog::kProtocolDeltat83P);
    }
    return "unknown";
}

std::optional<InputFormat> ParseInputFormat(const std::string& text) {
    if (text == "auto") return InputFormat::kAuto;
    if (text == "raw" || text == "83p") return InputFormat::kRaw;
    if (text == "pcap" || text == "pcapng") return InputFormat::kPcap;
    if (text == "lcm") return InputFormat::kLcmLog;
    return std::nullopt;
}

std::optional<Protocol> ParseProtocol(const std::string& text) {
    if (text == "auto") return Protocol::kAuto;
    if (text == lcmlog::kProtocolNovatel) return Protocol::kNovatel;
    if (text == "deltat" || text == lcmlog::kProtocolDeltat83P || text == "83p") {
        return Protocol::kDeltaT;
    }
    return std::nullopt;
}

void SourceSummary::Add(const SourceSummary& o) {
    bytes += o.bytes;
    chunks += o.chunks;
    frames_total += o.frames_total;
    log_frames += o.log_frames;
    responses += o.responses;
    prompts += o.prompts;
    for (const auto& [k, v] : o.frames_by_id) frames_by_id[k] += v;
    for (const auto& [k, v] : o.frames_by_kind) frames_by_kind[k] += v;
    crc_failures += o.crc_failures;
    for (std::size_t i = 0; i < protocol::kNumSkipReasons; ++i) {
        skipped.bytes[i] += o.skipped.bytes[i];
        skipped.events[i] += o.skipped.events[i];
    }
    truncated_tail_bytes += o.truncated_tail_bytes;
    unframed_bytes += o.unframed_bytes;
    datagram_errors += o.datagram_errors;
    if (o.gps_start_s) WidenGps(*this, *o.gps_start_s);
    if (o.gps_end_s) WidenGps(*this, *o.gps_end_s);
    if (o.sonar_start_utime) WidenSonar(*this, *o.sonar_start_utime);
    if (o.sonar_end_utime) WidenSonar(*this, *o.sonar_end_utime);
    decoded += o.decoded;
    unsupported += o.unsupported;
    for (const auto& [k, v] : o.decode_errors) decode_errors[k] += v;
    // Samples of several sources: the first ones in source order, the last of the last source.
    for (const auto& [type, theirs] : o.samples) {
        auto& mine = samples[type];
        mine.count += theirs.count;
        std::vector<nlohmann::json> tail = theirs.first;
        if (!theirs.last.is_null()) tail.push_back(theirs.last);
        const std::size_t limit = std::max(mine.first.size(), theirs.first.size());
        for (auto& j : tail) {
            if (mine.first.size() < limit) {
                mine.first.push_back(std::move(j));
            } else {
                mine.last = std::move(j);
            }
        }
    }
}

Expected<Detected> DetectFormat(ByteSpan bytes, const std::string& name) {
    if (capture::LooksLikeCapture(bytes)) return Detected{InputFormat::kPcap, Protocol::kAuto};
    if (bytes.size() >= 4 && ByteReader(bytes).U32Be() == 0xEDA1DA01u) {
        return Detected{InputFormat::kLcmLog, Protocol::kAuto};
    }
    if (LooksLikeDeltaT(bytes, name)) return Detected{InputFormat::kRaw, Protocol::kDeltaT};
    if (LooksLikeNovatel(bytes)) return Detected{InputFormat::kRaw, Protocol::kNovatel};
    if (bytes.empty()) return Error{name + ": the file is empty; cannot tell its format"};
    return Error{name +
                 ": cannot tell the format (not a pcap/pcapng capture, an LCM log, 83P records "
                 "or NovAtel data); give --format and --protocol"};
}

SourceSummary InspectStream(ByteSpan bytes,
                            Protocol protocol,
                            const InspectOptions& options,
                            const std::string& name) {
    const auto mode = protocol == Protocol::kDeltaT ? SourceCounter::Mode::kDeltaTStream
                                                    : SourceCounter::Mode::kNovatel;
    SourceCounter counter(name, ModeName(mode), mode, options.dump_first);
    const std::size_t chunk_bytes = std::max<std::size_t>(options.chunk_bytes, 1);
    for (std::size_t off = 0; off < bytes.size(); off += chunk_bytes) {
        counter.Push(bytes.subspan(off, std::min(chunk_bytes, bytes.size() - off)));
    }
    return counter.Finish();
}

Expected<InspectReport> InspectFile(const std::string& path, const InspectOptions& options) {
    auto bytes = capture::ReadFileBytes(path);
    if (!bytes) return bytes.error();
    InspectReport report;
    report.file = path;
    report.input_bytes = bytes->size();

    Detected detected;
    if (options.format == InputFormat::kAuto) {
        auto d = DetectFormat(*bytes, path);
        if (!d) return d.error();
        detected = *d;
    } else {
        detected.format = options.format;
        detected.protocol = LooksLikeDeltaT(*bytes, path) ? Protocol::kDeltaT : Protocol::kNovatel;
    }
    if (options.protocol != Protocol::kAuto) detected.protocol = options.protocol;
    report.format = detected.format;

    switch (detected.format) {
        case InputFormat::kPcap: {
            auto contents = capture::ParseCapture(*bytes, path);
            if (!contents) return contents.error();
            contents->stats.gzip = capture::IsGzipFile(path);
            return InspectCapture(std::move(contents).value(), options, std::move(report));
        }
        case InputFormat::kLcmLog:
            if (capture::IsGzipFile(path)) {
                return Error{path + ": gzip-compressed LCM logs are not supported; gunzip it"};
            }
            return InspectLcmLog(path, options, std::move(report));
        case InputFormat::kAuto:
        case InputFormat::kRaw:
            break;
    }
    report.sources.push_back(InspectStream(*bytes, detected.protocol, options, "file"));
    report.total.Add(report.sources.back());
    return report;
}

}  // namespace pitmap::tools::inspect
