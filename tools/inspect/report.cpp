// SPDX-License-Identifier: MIT
// Text and JSON renderings of an InspectReport.
#include <algorithm>
#include <cctype>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "common/protocol/novatel/framer.hpp"
#include "tools/inspect/inspect.hpp"

namespace pitmap::tools::inspect {
namespace {

using nlohmann::json;

constexpr double kSecondsPerWeek = 604800.0;

// "42" -> BESTPOS, "1R" -> LOG; "" for keys that are not binary ids or unknown ids.
std::string NameForKey(const std::string& key) {
    std::string digits = key;
    if (!digits.empty() && digits.back() == 'R') digits.pop_back();
    if (digits.empty() || digits.size() > 5 ||
        digits.find_first_not_of("0123456789") != std::string::npos) {
        return "";
    }
    const unsigned long id = std::stoul(digits);
    if (id > 0xFFFF) return "";
    return std::string(protocol::novatel::MessageNameFromId(static_cast<std::uint16_t>(id)));
}

// Seconds rounded to the millisecond, so the JSON does not carry binary noise.
double RoundMs(double s) {
    return std::round(s * 1000.0) / 1000.0;
}

json GpsTime(double gps_s) {
    const double week = std::floor(gps_s / kSecondsPerWeek);
    return json{{"week", static_cast<std::int64_t>(week)},
                {"tow_s", RoundMs(gps_s - week * kSecondsPerWeek)}};
}

json TimeSpan(const SourceSummary& s) {
    json span = json::object();
    if (s.gps_start_s && s.gps_end_s) {
        span["gps_start"] = GpsTime(*s.gps_start_s);
        span["gps_end"] = GpsTime(*s.gps_end_s);
        span["duration_s"] = RoundMs(*s.gps_end_s - *s.gps_start_s);
    }
    if (s.sonar_start_utime && s.sonar_end_utime) {
        span["sonar_header_start_utime"] = *s.sonar_start_utime;
        span["sonar_header_end_utime"] = *s.sonar_end_utime;
        span["duration_s"] =
            RoundMs(static_cast<double>(*s.sonar_end_utime - *s.sonar_start_utime) / 1e6);
    }
    return span.empty() ? json(nullptr) : span;
}

json Skipped(const protocol::SkipCounters& skipped) {
    json out = json::object();
    out["total"] = skipped.TotalBytes();
    for (std::size_t i = 0; i < protocol::kNumSkipReasons; ++i) {
        out[std::string(protocol::ToString(static_cast<protocol::SkipReason>(i)))] =
            skipped.bytes[i];
    }
    return out;
}

json Counts(const SourceSummary& s) {
    json out = json::object();
    out["frames_total"] = s.frames_total;
    out["log_frames"] = s.log_frames;
    out["responses"] = s.responses;
    out["prompts"] = s.prompts;
    out["frames_by_id"] = s.frames_by_id;
    out["frames_by_kind"] = s.frames_by_kind;
    json names = json::object();
    for (const auto& [key, count] : s.frames_by_id) {
        const std::string name = NameForKey(key);
        if (!name.empty()) names[key] = name;
    }
    out["message_names"] = names;
    out["crc_failures"] = s.crc_failures;
    out["skipped_bytes"] = Skipped(s.skipped);
    out["truncated_tail_bytes"] = s.truncated_tail_bytes;
    out["unframed_bytes"] = s.unframed_bytes;
    out["datagram_errors"] = s.datagram_errors;
    out["time_span"] = TimeSpan(s);
    out["decoded"] = s.decoded;
    out["unsupported"] = s.unsupported;
    out["decode_errors"] = s.decode_errors;
    if (!s.samples.empty()) {
        json samples = json::object();
        for (const auto& [name, sample] : s.samples) {
            samples[name] =
                json{{"count", sample.count}, {"first", sample.first}, {"last", sample.last}};
        }
        out["samples"] = std::move(samples);
    }
    return out;
}

std::string FormatGps(double gps_s) {
    const double week = std::floor(gps_s / kSecondsPerWeek);
    char buf[64];
    std::snprintf(buf, sizeof(buf), "week %.0f %.3f s", week, gps_s - week * kSecondsPerWeek);
    return buf;
}

void WriteCounts(std::ostringstream& os, const SourceSummary& s, const std::string& indent) {
    os << indent << "bytes " << s.bytes << " in " << s.chunks << " chunks, frames "
       << s.frames_total << " (logs " << s.log_frames << ", responses " << s.responses
       << ", prompts " << s.prompts << ")\n";
    // Binary ids in numeric order first, then the text keys.
    std::vector<std::pair<std::string, std::uint64_t>> rows(s.frames_by_id.begin(),
                                                            s.frames_by_id.end());
    const auto numeric = [](const std::string& k) {
        return !k.empty() && std::isdigit(static_cast<unsigned char>(k[0])) != 0;
    };
    std::stable_sort(rows.begin(), rows.end(), [&](const auto& a, const auto& b) {
        if (numeric(a.first) != numeric(b.first)) return numeric(a.first);
        if (numeric(a.first)) {
            const unsigned long ia = std::stoul(a.first);  // "36R" -> 36
            const unsigned long ib = std::stoul(b.first);
            if (ia != ib) return ia < ib;
        }
        return a.first < b.first;
    });
    for (const auto& [key, count] : rows) {
        const std::string name = NameForKey(key);
        char line[160];
        std::snprintf(line,
                      sizeof(line),
                      "%s  %-22s %-22s %" PRIu64 "\n",
                      indent.c_str(),
                      key.c_str(),
                      name.c_str(),
                      count);
        os << line;
    }
    os << indent << "CRC failures " << s.crc_failures << ", skipped bytes "
       << s.skipped.TotalBytes();
    for (std::size_t i = 0; i < protocol::kNumSkipReasons; ++i) {
        if (s.skipped.bytes[i] == 0) continue;
        os << ", " << protocol::ToString(static_cast<protocol::SkipReason>(i)) << " "
           << s.skipped.bytes[i] << " (" << s.skipped.events[i] << "x)";
    }
    os << ", truncated tail " << s.truncated_tail_bytes << "\n";
    if (s.unframed_bytes != 0) os << indent << "unframed bytes " << s.unframed_bytes << "\n";
    if (s.datagram_errors != 0) os << indent << "bad datagrams " << s.datagram_errors << "\n";
    os << indent << "decoded " << s.decoded << ", no decoder " << s.unsupported;
    for (const auto& [kind, count] : s.decode_errors) os << ", " << kind << " " << count;
    os << "\n";
    for (const auto& [name, sample] : s.samples) {
        os << indent << name << " x" << sample.count << ": first " << sample.first.front().dump()
           << "\n";
        if (!sample.last.is_null()) os << indent << "  last " << sample.last.dump() << "\n";
    }
    if (s.gps_start_s && s.gps_end_s) {
        os << indent << "GPS time " << FormatGps(*s.gps_start_s) << " .. "
           << FormatGps(*s.gps_end_s) << " (" << (*s.gps_end_s - *s.gps_start_s) << " s)\n";
    }
    if (s.sonar_start_utime && s.sonar_end_utime) {
        os << indent << "sonar header time " << *s.sonar_start_utime << " .. " << *s.sonar_end_utime
           << " us (Unix)\n";
    }
}

}  // namespace

nlohmann::json ToJson(const InspectReport& report) {
    json out = json::object();
    out["file"] = std::filesystem::path(report.file).filename().string();
    out["format"] = ToString(report.format);
    out["input_bytes"] = report.input_bytes;
    out.update(Counts(report.total));
    json sources = json::array();
    for (const auto& s : report.sources) {
        json src = json::object();
        src["name"] = s.name;
        src["protocol"] = s.protocol;
        src["bytes"] = s.bytes;
        src["chunks"] = s.chunks;
        src.update(Counts(s));
        sources.push_back(std::move(src));
    }
    out["sources"] = std::move(sources);
    if (report.capture) {
        const auto& c = *report.capture;
        json tcp = json::array();
        for (const auto& t : c.tcp) {
            tcp.push_back(json{{"stream", t.name},
                               {"bytes", t.bytes},
                               {"packets", t.packets},
                               {"payload_segments", t.payload_segments},
                               {"retransmitted_segments", t.retransmitted_segments},
                               {"retransmitted_bytes", t.retransmitted_bytes},
                               {"out_of_order_segments", t.out_of_order_segments},
                               {"gaps", t.gaps},
                               {"gap_bytes", t.gap_bytes}});
        }
        out["capture"] = json{{"format", c.format},
                              {"gzip", c.gzip},
                              {"link_type", c.link_type},
                              {"packets", c.packets},
                              {"tcp_packets", c.tcp_packets},
                              {"udp_packets", c.udp_packets},
                              {"other_packets", c.other_packets},
                              {"truncated_packets", c.truncated_packets},
                              {"first_utime", c.first_utime},
                              {"last_utime", c.last_utime},
                              {"read_error", c.read_error},
                              {"udp_datagrams", c.udp_datagrams},
                              {"tcp", std::move(tcp)}};
    }
    if (report.lcm) {
        const auto& l = *report.lcm;
        json channels = json::object();
        for (const auto& [name, ch] : l.channels) {
            channels[name] = json{{"type", ch.type}, {"events", ch.events}, {"bytes", ch.bytes}};
        }
        out["lcm"] = json{{"events", l.events},
                          {"first_utime", l.first_utime},
                          {"last_utime", l.last_utime},
                          {"raw_seq_gaps", l.raw_seq_gaps},
                          {"raw_seq_jumps", l.raw_seq_jumps},
                          {"corrupt_headers", l.corrupt_headers},
                          {"resync_bytes", l.resync_bytes},
                          {"length_repairs", l.length_repairs},
                          {"truncated_bytes", l.truncated_bytes},
                          {"undecodable_events", l.undecodable_events},
                          {"channels", std::move(channels)}};
    }
    return out;
}

std::string ToText(const InspectReport& report) {
    std::ostringstream os;
    os << report.file << ": " << ToString(report.format) << ", " << report.input_bytes
       << " bytes\n";
    if (report.capture) {
        const auto& c = *report.capture;
        os << "capture: " << c.format << (c.gzip ? " (gzip)" : "") << ", link " << c.link_type
           << ", " << c.packets << " packets (TCP " << c.tcp_packets << ", UDP " << c.udp_packets
           << ", other " << c.other_packets << ", truncated " << c.truncated_packets << ")\n";
        if (!c.read_error.empty()) os << "  read error: " << c.read_error << "\n";
        for (const auto& t : c.tcp) {
            os << "  tcp " << t.name << ": " << t.bytes << " bytes, " << t.payload_segments
               << " data segments, retransmitted " << t.retransmitted_segments << " ("
               << t.retransmitted_bytes << " bytes), out of order " << t.out_of_order_segments
               << ", gaps " << t.gaps << " (" << t.gap_bytes << " bytes missing)\n";
        }
    }
    if (report.lcm) {
        const auto& l = *report.lcm;
        os << "LCM log: " << l.events << " events, raw chunks missing by seq " << l.raw_seq_gaps;
        if (l.raw_seq_jumps > 0) os << " (" << l.raw_seq_jumps << " implausible seq jumps)";
        os << "\n";
        if (l.corrupt_headers + l.resync_bytes + l.length_repairs + l.truncated_bytes +
                l.undecodable_events >
            0) {
            os << "  damage: " << l.corrupt_headers << " corrupt event headers, " << l.resync_bytes
               << " bytes skipped to resynchronise, " << l.length_repairs
               << " event lengths repaired, " << l.truncated_bytes << " bytes cut at the end, "
               << l.undecodable_events << " raw events that do not decode\n";
        }
        for (const auto& [name, ch] : l.channels) {
            os << "  " << name << ": " << ch.type << " x" << ch.events << "\n";
        }
    }
    for (const auto& s : report.sources) {
        os << "source " << s.name << " (" << s.protocol << ")\n";
        WriteCounts(os, s, "  ");
    }
    if (report.sources.size() > 1) {
        os << "total\n";
        WriteCounts(os, report.total, "  ");
    }
    return os.str();
}

}  // namespace pitmap::tools::inspect
