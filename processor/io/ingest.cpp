// SPDX-License-Identifier: MIT
#include "processor/io/ingest.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <pitmap/gps_time_t.hpp>
#include <pitmap/ins_pva_t.hpp>
#include <pitmap/ins_stddev_t.hpp>
#include <pitmap/multibeam_ping_t.hpp>
#include <pitmap/raw_bytes_t.hpp>
#include <type_traits>
#include <variant>

#include "common/clock/ping_time.hpp"
#include "common/frames.hpp"
#include "common/gps_time.hpp"
#include "common/protocol/deltat/stream_framer.hpp"
#include "common/protocol/novatel/decoder.hpp"
#include "lcmtypes/log/channels.hpp"
#include "lcmtypes/log/lcm_log_reader.hpp"
#include "lcmtypes/log/lcm_wire.hpp"
#include "processor/io/ingest_collect.hpp"
#include "processor/io/ingest_sessions.hpp"
#include "processor/io/lcm_messages.hpp"
#include "processor/io/xtf.hpp"

namespace pitmap::proc::io {

namespace fs = std::filesystem;
namespace nv = pitmap::protocol::novatel;
namespace dt = pitmap::protocol::deltat;
using survey::NavSample;
using survey::NavStdDev;
using survey::PingHeader;

const char* ToString(IngestSource s) {
    switch (s) {
        case IngestSource::kAuto:
            return "auto";
        case IngestSource::kDecoded:
            return "decoded";
        case IngestSource::kRaw:
            return "raw";
    }
    return "auto";
}

bool ParseIngestSource(const std::string& t, IngestSource& out) {
    if (t == "auto")
        out = IngestSource::kAuto;
    else if (t == "decoded")
        out = IngestSource::kDecoded;
    else if (t == "raw")
        out = IngestSource::kRaw;
    else
        return false;
    return true;
}

std::vector<std::string> IngestConfig::Validate() const {
    std::vector<std::string> p;
    if (!std::isfinite(sonar_clock_offset_s))
        p.push_back("ingest.sonar_clock_offset_s must be finite");
    for (const std::string& problem : sonar_clock.Validate()) p.push_back("ingest." + problem);
    if (!(degraded_ins_sigma_m >= 0 && degraded_ins_sigma_m <= 1000))
        p.push_back("ingest.degraded_ins_sigma_m must lie in [0, 1000]");
    if (!(degraded_ins_sigma_deg >= 0 && degraded_ins_sigma_deg <= 180))
        p.push_back("ingest.degraded_ins_sigma_deg must lie in [0, 180]");
    if (!(session_gap_s >= 1 && session_gap_s <= 30 * 86400.0))
        p.push_back("ingest.session_gap_s must lie in [1, 2592000]");
    if (!(max_session_speed_mps > 0 && std::isfinite(max_session_speed_mps)))
        p.push_back("ingest.max_session_speed_mps must be > 0");
    if (!(report_gap_s > 0 && std::isfinite(report_gap_s)))
        p.push_back("ingest.report_gap_s must be > 0");
    if (session < 0) p.push_back("ingest.session must be >= 0 (0 = the inputs hold one)");
    for (const std::string* id : {&nav_channel_id, &sonar_channel_id}) {
        for (char c : *id) {
            if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') {
                p.push_back("ingest channel id '" + *id + "' may hold only letters, digits and _");
                break;
            }
        }
    }
    return p;
}

namespace {

using namespace detail;  // NOLINT(google-build-using-namespace): ingest.cpp's own internals

// What one pass over the logs reads.
struct ReadLogsOptions {
    bool decoded = false;           // the decoded channels (INS_PVA_, INS_STDDEV_, GPS_TIME_, ...)
    bool raw_nav = false;           // re-decode raw NovAtel chunks
    bool raw_sonar = false;         // re-decode raw 83P chunks
    bool count_events = false;      // count files, bytes, events and damage (the first pass only)
    ProgressCallback progress;      // empty: no progress
    std::uint64_t total_bytes = 0;  // of all paths, for the progress fraction
};

// What one pass saw.
struct Pass {
    bool decoded_nav = false;
    bool decoded_sonar = false;
    bool raw_nav = false;
    bool raw_sonar = false;
    std::int64_t raw_event_failures = 0;  // raw_bytes_t events that did not decode
};

// What a pass carries from event to event: the collector, the id filters, the raw streams
// (framers and clock models per raw channel) and the decode buffers, reused so that an event
// allocates only what its message needs.
struct LogReadState {
    LogReadState(IngestResult& r, const IngestConfig& ingest_config)
        : col(r),
          config(ingest_config),
          nav_id(Upper(ingest_config.nav_channel_id)),
          sonar_id(Upper(ingest_config.sonar_channel_id)) {}
    Collector col;
    const IngestConfig& config;
    const std::string nav_id;
    const std::string sonar_id;
    std::map<std::string, RawStream, std::less<>> raw_streams;
    pitmap::ins_pva_t pva;
    pitmap::ins_stddev_t sd;
    pitmap::gps_time_t gt;
    pitmap::multibeam_ping_t mb;
    std::vector<std::uint16_t> intensity_buf;  // a ping's intensities, clamped to 0..65535
    pitmap::raw_bytes_t raw;
    dt::Ping83P ping83;
};

// The fraction of the logs' bytes read, reported every 16384 events.
class LogProgress {
public:
    LogProgress(const ProgressCallback& callback, std::uint64_t total_bytes)
        : callback_(callback), total_bytes_(total_bytes) {}
    void StartFile() {
        last_position_ = 0;
        events_ = 0;
    }
    void AfterEvent(const lcmlog::LcmLogReader& reader) {
        if (!callback_ || (++events_ & 0x3FFF) != 0) return;
        bytes_done_ += reader.position() - last_position_;
        last_position_ = reader.position();
        callback_(total_bytes_ ? static_cast<double>(bytes_done_) / total_bytes_ : 0.0);
    }
    void EndFile(const lcmlog::LcmLogReader& reader) {
        bytes_done_ += reader.size() - last_position_;
    }

private:
    const ProgressCallback& callback_;
    const std::uint64_t total_bytes_;
    std::uint64_t bytes_done_ = 0;
    std::uint64_t last_position_ = 0;
    std::int64_t events_ = 0;
};

void CountEvent(std::string_view channel, IngestCounts& c) {
    ++c.events;
    auto it = c.events_by_channel.find(std::string(channel));
    if (it == c.events_by_channel.end()) {
        c.events_by_channel.emplace(std::string(channel), 1);
    } else {
        ++it->second;
    }
}

// Each decode below is bounds-checked against the event's own bytes first: a corrupted count is
// a counted decode failure, never an exception or a huge allocation.

void AddInsPva(const lcmlog::LcmEvent& ev, LogReadState& st, IngestCounts& c) {
    if (!lcmlog::DecodeChecked(st.pva, ev.data.data(), ev.data.size())) {
        ++c.decode_failures;
        return;
    }
    st.col.AddNav(NavSampleOf(st.pva));
    if (st.pva.has_stddev) st.col.AddStdDev(NavStdDevOf(st.pva));
}

void AddInsStdDev(const lcmlog::LcmEvent& ev, LogReadState& st, IngestCounts& c) {
    if (!lcmlog::DecodeChecked(st.sd, ev.data.data(), ev.data.size())) {
        ++c.decode_failures;
        return;
    }
    st.col.AddStdDev(NavStdDevOf(st.sd));
}

void AddGpsTime(const lcmlog::LcmEvent& ev, LogReadState& st, IngestCounts& c) {
    if (!lcmlog::DecodeChecked(st.gt, ev.data.data(), ev.data.size())) {
        ++c.decode_failures;
        return;
    }
    st.col.AddLeapSeconds(st.gt.utc_offset_s, st.gt.utc_status);
}

void AddMultibeamPing(const lcmlog::LcmEvent& ev, LogReadState& st, IngestCounts& c) {
    const pitmap::multibeam_ping_t& mb = st.mb;
    if (!lcmlog::DecodeChecked(st.mb, ev.data.data(), ev.data.size())) {
        ++c.decode_failures;
        return;
    }
    PingHeader h = PingHeaderOf(mb);
    // Intensities only when the ping says so and they match the beams (a log that disagrees
    // with itself keeps its ranges, without intensities).
    const bool with = mb.intensity_included != 0 && mb.num_intensities > 0 &&
                      mb.intensities.size() == mb.range_counts.size();
    st.intensity_buf.resize(with ? mb.intensities.size() : 0);
    for (std::size_t i = 0; i < st.intensity_buf.size(); ++i) {
        st.intensity_buf[i] =
            static_cast<std::uint16_t>(std::clamp<std::int32_t>(mb.intensities[i], 0, 65535));
    }
    st.col.AddPing(h,
                   mb.range_counts.data(),
                   mb.range_counts.size(),
                   with ? st.intensity_buf.data() : nullptr);
}

// A NovAtel chunk into its stream's framer, the frames it completes into the collector.
void AddNovatelChunk(ByteSpan bytes, RawStream& s, Collector& col, IngestCounts& c) {
    if (!s.novatel) s.novatel = std::make_unique<nv::Framer>();
    s.novatel->Push(bytes);
    DrainNovatel(s, col, c);
}

// An 83P chunk, stamped as the daemon stamped it: a UDP datagram is one record, a serial
// stream is framed across chunks.
void AddSonarChunk(ByteSpan bytes, RawStream& s, LogReadState& st, IngestCounts& c) {
    const pitmap::raw_bytes_t& raw = st.raw;
    if (!s.stamper) s.stamper = std::make_unique<clock::PingStamper>(st.config.sonar_clock);
    s.last_chunk = {
        .utime_host = raw.utime, .utime_gps = raw.utime_gps, .utime_kernel = raw.utime_kernel};
    if (raw.transport == pitmap::raw_bytes_t::TRANSPORT_UDP) {
        auto d = dt::DecodeDatagramInto(bytes, s.float_order, st.ping83);
        if (std::holds_alternative<dt::DecodeError>(d)) {
            ++c.pings_bad;
        } else if (std::get<dt::RecordKind>(d) == dt::RecordKind::kPing) {
            AddRawPing(s, st.col, st.ping83);
        }
    } else {
        if (!s.deltat) s.deltat = std::make_unique<dt::StreamFramer>();
        s.deltat->Push(bytes);
        DrainDeltat(s, st.col, c, st.ping83);
    }
}

// RAW_<id>: which source the chunk is from is noted in `seen`; it is re-decoded only when the
// options want that source. Once both sources are seen and neither is wanted, raw events are
// not even decoded.
void AddRawEvent(const lcmlog::LcmEvent& ev,
                 const ReadLogsOptions& options,
                 LogReadState& st,
                 Pass& seen,
                 IngestCounts& c) {
    const std::string_view ch = ev.channel;
    const std::string_view raw_id = ch.substr(lcmlog::kChannelRaw.size());
    const bool nav_ok = st.nav_id.empty() || raw_id == st.nav_id;
    const bool sonar_ok = st.sonar_id.empty() || raw_id == st.sonar_id;
    if (!options.raw_nav && !options.raw_sonar && seen.raw_nav && seen.raw_sonar) return;
    if (!lcmlog::DecodeChecked(st.raw, ev.data.data(), ev.data.size())) {
        ++c.decode_failures;
        ++seen.raw_event_failures;
        return;
    }
    const bool is_nav = st.raw.protocol == lcmlog::kProtocolNovatel && nav_ok;
    const bool is_sonar = st.raw.protocol == lcmlog::kProtocolDeltat83P && sonar_ok;
    seen.raw_nav = seen.raw_nav || is_nav;
    seen.raw_sonar = seen.raw_sonar || is_sonar;
    if (!((is_nav && options.raw_nav) || (is_sonar && options.raw_sonar))) return;
    ++c.raw_chunks_decoded;
    RawStream& s = st.raw_streams[std::string(ch)];
    const ByteSpan bytes(st.raw.data.data(), st.raw.data.size());
    if (is_nav) {
        AddNovatelChunk(bytes, s, st.col, c);
    } else {
        AddSonarChunk(bytes, s, st, c);
    }
}

// One event by its channel: the decoded channels when the options want them, the raw ones
// through AddRawEvent; `seen` notes which kinds the logs hold either way.
void ReadLogEvent(const lcmlog::LcmEvent& ev,
                  const ReadLogsOptions& options,
                  LogReadState& st,
                  Pass& seen,
                  IngestCounts& c) {
    const std::string_view ch = ev.channel;
    if (lcmlog::ChannelMatches(ch, lcmlog::kChannelInsPva, st.nav_id)) {
        seen.decoded_nav = true;
        if (options.decoded) AddInsPva(ev, st, c);
    } else if (lcmlog::ChannelMatches(ch, lcmlog::kChannelInsStdDev, st.nav_id)) {
        if (options.decoded) AddInsStdDev(ev, st, c);
    } else if (StartsWith(ch, lcmlog::kChannelGpsTime)) {
        if (options.decoded) AddGpsTime(ev, st, c);
    } else if (lcmlog::ChannelMatches(ch, lcmlog::kChannelMultibeamPing, st.sonar_id)) {
        seen.decoded_sonar = true;
        if (options.decoded) AddMultibeamPing(ev, st, c);
    } else if (StartsWith(ch, lcmlog::kChannelRaw)) {
        AddRawEvent(ev, options, st, seen, c);
    }
}

// One log file's bytes and the damage its reader skipped or repaired.
void AddLogFileCounts(const lcmlog::LcmLogReader& reader, IngestCounts& c) {
    const lcmlog::LcmLogCounts& lc = reader.counts();
    ++c.files;
    c.bytes += static_cast<std::int64_t>(reader.size());
    c.corrupt_events += lc.corrupt_headers;
    c.resync_bytes += lc.resync_bytes;
    c.truncated_events += lc.truncated_events;
    c.length_repairs += lc.length_repairs;
}

// End of the logs: a candidate still waiting gives up its sync only; what it held is framed
// again (frames behind a false header are not lost).
void FlushRawStreams(LogReadState& st, IngestCounts& c) {
    for (auto& [name, s] : st.raw_streams) {
        if (s.novatel) {
            while (auto sk = s.novatel->Flush()) {
                c.raw_skipped_bytes += static_cast<std::int64_t>(sk->bytes);
                DrainNovatel(s, st.col, c);
            }
        }
        if (s.deltat) {
            while (auto sk = s.deltat->Flush()) {
                c.raw_skipped_bytes += static_cast<std::int64_t>(sk->bytes);
                DrainDeltat(s, st.col, c, st.ping83);
            }
        }
    }
}

Status ReadLogs(const std::vector<std::string>& paths,
                const IngestConfig& config,
                const ReadLogsOptions& options,
                IngestResult& r,
                Pass& seen) {
    LogReadState st(r, config);
    LogProgress progress(options.progress, options.total_bytes);
    for (const std::string& path : paths) {
        auto reader = lcmlog::LcmLogReader::Open(path);
        if (!reader) return reader.error();
        const detail::SpanMark mark = detail::MarkSpan(r);
        progress.StartFile();
        lcmlog::LcmEvent ev;
        while ((*reader)->Next(ev)) {
            if (options.count_events) CountEvent(ev.channel, r.counts);
            ReadLogEvent(ev, options, st, seen, r.counts);
            progress.AfterEvent(**reader);
        }
        progress.EndFile(**reader);
        detail::RecordSpan(r, path, mark);
        if (options.count_events) AddLogFileCounts(**reader, r.counts);
    }
    FlushRawStreams(st, r.counts);
    return Ok{};
}

void SetTotals(IngestResult& r);

// Sorts and deduplicates the series; with `config` the INS status rule is applied first, to
// every message read (IngestLcmLogs and IngestNovatelFiles; IngestFiles merges what they did).
void Finish(IngestResult& r, const IngestConfig* config = nullptr) {
    // Prefer INSPVA(S) samples over INSPVAX ones at the same time (the latter carry a float
    // undulation).
    std::stable_sort(r.nav.samples.begin(), r.nav.samples.end(), [](const auto& a, const auto& b) {
        if (a.utime_gps != b.utime_gps) return a.utime_gps < b.utime_gps;
        return (a.position_type == -1) > (b.position_type == -1);
    });
    if (config) detail::ApplyInsStatusRule(r, *config);
    const std::size_t nav_before = r.nav.samples.size();
    const std::size_t pings_before = r.pings.pings.size();
    std::vector<std::int64_t> nav_conflicts, ping_conflicts;
    survey::SortAndDeduplicate(r.nav, &nav_conflicts);
    survey::SortAndDeduplicate(r.pings, &ping_conflicts);
    r.counts.nav_conflicts += static_cast<std::int64_t>(nav_conflicts.size());
    r.counts.ping_conflicts += static_cast<std::int64_t>(ping_conflicts.size());
    r.counts.nav_duplicates += static_cast<std::int64_t>(nav_before - r.nav.samples.size()) -
                               static_cast<std::int64_t>(nav_conflicts.size());
    r.counts.ping_duplicates += static_cast<std::int64_t>(pings_before - r.pings.pings.size());
    for (const auto* c : {&nav_conflicts, &ping_conflicts}) {
        r.conflict_times.insert(r.conflict_times.end(), c->begin(), c->end());
    }
    SetTotals(r);
}

// The sample totals and the one-line message, after anything that changed the series.
void SetTotals(IngestResult& r) {
    r.counts.nav_samples = static_cast<std::int64_t>(r.nav.samples.size());
    r.counts.stddev_samples = static_cast<std::int64_t>(r.nav.stddevs.size());
    r.counts.pings = static_cast<std::int64_t>(r.pings.pings.size());
    r.message = std::to_string(r.counts.nav_samples) + " INS samples" +
                (r.nav_from_raw ? " (re-decoded)" : "") + ", " + std::to_string(r.counts.pings) +
                " pings" + (r.pings_from_raw ? " (re-decoded)" : "") + ", " +
                std::to_string(r.pings.num_soundings()) + " soundings";
}

enum class FileKind { kLcm, k83P, kXtf, kNovatel, kUnknown };

FileKind Sniff(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::uint8_t b[4] = {0, 0, 0, 0};
    in.read(reinterpret_cast<char*>(b), 4);
    if (in.gcount() < 3) return FileKind::kUnknown;
    if (in.gcount() == 4 && b[0] == 0xED && b[1] == 0xA1 && b[2] == 0xDA && b[3] == 0x01) {
        return FileKind::kLcm;
    }
    if (b[0] == '8' && b[1] == '3' && b[2] == 'P') return FileKind::k83P;
    if (IsXtfFile(path)) return FileKind::kXtf;
    std::string ext = fs::path(path).extension().string();
    for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (ext == ".lcmlog") return FileKind::kLcm;
    if (ext == ".83p") return FileKind::k83P;
    return FileKind::kNovatel;  // binary (0xAA 0x44 ...) or ASCII ('#', '%', '<'), found by framing
}

}  // namespace

IngestCounts& IngestCounts::operator+=(const IngestCounts& o) {
    files += o.files;
    bytes += o.bytes;
    events += o.events;
    corrupt_events += o.corrupt_events;
    resync_bytes += o.resync_bytes;
    truncated_events += o.truncated_events;
    length_repairs += o.length_repairs;
    files_skipped += o.files_skipped;
    decode_failures += o.decode_failures;
    nav_samples += o.nav_samples;
    nav_without_time += o.nav_without_time;
    nav_not_good += o.nav_not_good;
    nav_not_navigating += o.nav_not_navigating;
    nav_degraded += o.nav_degraded;
    nav_conflicts += o.nav_conflicts;
    ping_conflicts += o.ping_conflicts;
    nav_gaps += o.nav_gaps;
    ping_gaps += o.ping_gaps;
    sessions += o.sessions;
    nav_duplicates += o.nav_duplicates;
    stddev_samples += o.stddev_samples;
    pings += o.pings;
    pings_without_time += o.pings_without_time;
    pings_bad += o.pings_bad;
    ping_duplicates += o.ping_duplicates;
    raw_chunks_decoded += o.raw_chunks_decoded;
    raw_skipped_bytes += o.raw_skipped_bytes;
    raw_decode_errors += o.raw_decode_errors;
    for (const auto& [channel, n] : o.events_by_channel) events_by_channel[channel] += n;
    return *this;
}

Expected<IngestResult> IngestLcmLogs(const std::vector<std::string>& paths,
                                     const IngestConfig& config,
                                     const ProgressCallback& progress) {
    if (paths.empty()) return Error{"no log files given"};
    std::uint64_t total = 0;
    for (const auto& p : paths) {
        std::error_code ec;
        const auto sz = fs::file_size(p, ec);
        if (ec) return Error{p + ": cannot read: " + ec.message()};
        total += sz;
    }
    const bool raw = config.source == IngestSource::kRaw;
    IngestResult r;
    Pass seen;
    if (auto s = ReadLogs(paths,
                          config,
                          {.decoded = !raw,
                           .raw_nav = raw,
                           .raw_sonar = raw,
                           .count_events = true,
                           .progress = progress,
                           .total_bytes = total},
                          r,
                          seen);
        !s) {
        return s.error();
    }
    r.nav_from_raw = raw;
    r.pings_from_raw = raw;
    if (config.source == IngestSource::kAuto) {
        const bool need_nav = !seen.decoded_nav && seen.raw_nav;
        const bool need_sonar = !seen.decoded_sonar && seen.raw_sonar;
        if (need_nav || need_sonar) {
            IngestResult extra;
            Pass seen2;
            if (auto s = ReadLogs(paths,
                                  config,
                                  {.decoded = false,
                                   .raw_nav = need_nav,
                                   .raw_sonar = need_sonar,
                                   .count_events = false,
                                   .progress = {},
                                   .total_bytes = total},
                                  extra,
                                  seen2);
                !s) {
                return s.error();
            }
            detail::TakeSpans(r, extra, need_nav, need_sonar);
            if (need_nav) {
                r.nav.samples = std::move(extra.nav.samples);
                r.nav.stddevs = std::move(extra.nav.stddevs);
                if (extra.nav.leap_seconds >= 0) r.nav.leap_seconds = extra.nav.leap_seconds;
                r.nav_from_raw = true;
            }
            if (need_sonar) {
                r.pings = std::move(extra.pings);
                r.pings_from_raw = true;
            }
            // The second pass counts no files, events or damage (count_events is off) and
            // decodes every raw event: the raw events the first pass already found
            // undecodable are not counted twice.
            extra.counts.decode_failures -=
                std::min(seen.raw_event_failures, seen2.raw_event_failures);
            r.counts += extra.counts;
        }
    }
    if (progress) progress(1.0);
    Finish(r, &config);
    return r;
}

Expected<IngestResult> IngestNovatelFiles(const std::vector<std::string>& paths,
                                          const IngestConfig& config) {
    IngestResult r;
    Collector col(r);
    for (const std::string& path : paths) {
        std::ifstream in(path, std::ios::binary);
        if (!in) return Error{path + ": cannot open"};
        const detail::SpanMark mark = detail::MarkSpan(r);
        RawStream s;
        s.novatel = std::make_unique<nv::Framer>();
        std::vector<std::uint8_t> buf(1 << 16);
        while (in) {
            in.read(reinterpret_cast<char*>(buf.data()), static_cast<std::streamsize>(buf.size()));
            const auto got = static_cast<std::size_t>(in.gcount());
            if (got == 0) break;
            r.counts.bytes += static_cast<std::int64_t>(got);
            s.novatel->Push(ByteSpan(buf.data(), got));
            DrainNovatel(s, col, r.counts);
        }
        while (auto sk = s.novatel->Flush()) {
            r.counts.raw_skipped_bytes += static_cast<std::int64_t>(sk->bytes);
            DrainNovatel(s, col, r.counts);
        }
        detail::RecordSpan(r, path, mark);
        ++r.counts.files;
    }
    r.nav_from_raw = true;
    Finish(r, &config);
    return r;
}

Status Ingest83PFiles(const std::vector<std::string>& paths,
                      const IngestConfig& config,
                      int leap_seconds,
                      IngestResult& into) {
    Collector col(into);
    dt::Ping83P ping;
    for (const std::string& path : paths) {
        std::ifstream in(path, std::ios::binary);
        if (!in) return Error{path + ": cannot open"};
        const detail::SpanMark mark = detail::MarkSpan(into);
        RawStream s;
        s.deltat = std::make_unique<dt::StreamFramer>();
        std::vector<std::uint8_t> buf(1 << 16);
        // A vendor file is written whole: every skipped byte is damage (a record cut short by a
        // full disk or a copy, garbage between records), so each is a warning with its offset
        // (the first few of a file, then their total), besides the count.
        constexpr int kMaxSkipWarnings = 5;
        int skip_events = 0;
        std::uint64_t skipped_unwarned = 0;
        const auto skipped = [&](const protocol::Skipped& sk) {
            into.counts.raw_skipped_bytes += static_cast<std::int64_t>(sk.bytes);
            if (++skip_events > kMaxSkipWarnings) {
                skipped_unwarned += sk.bytes;
                return;
            }
            const std::string what = sk.reason == protocol::SkipReason::kTruncated
                                         ? "a record cut short at the end of the file"
                                         : "bytes that are no 83P record (" +
                                               std::string(protocol::ToString(sk.reason)) + ")";
            into.warnings.push_back(path + ": " + what + ": " + std::to_string(sk.bytes) +
                                    " bytes skipped at byte offset " + std::to_string(sk.offset));
        };
        const auto drain = [&] {
            while (true) {
                auto ev = s.deltat->Next();
                if (std::holds_alternative<protocol::NeedMore>(ev)) break;
                if (auto* sk = std::get_if<protocol::Skipped>(&ev)) {
                    skipped(*sk);
                    continue;
                }
                auto d =
                    dt::DecodeRecord83PInto(std::get<dt::Record>(ev).bytes, s.float_order, ping);
                if (std::holds_alternative<dt::DecodeError>(d)) {
                    ++into.counts.pings_bad;
                    continue;
                }
                if (std::get<dt::RecordKind>(d) != dt::RecordKind::kPing) continue;
                std::int64_t t = 0;
                if (ping.header_time_valid) {
                    // The offset is the sonar clock minus UTC: subtracted (ingest.hpp).
                    t = (leap_seconds >= 0 ? GpsFromUnix(ping.utime_sonar_header, leap_seconds)
                                           : GpsFromUnix(ping.utime_sonar_header)) -
                        std::llround(config.sonar_clock_offset_s * 1e6);
                }
                col.AddPing83P(ping, t);
                into.pings.clock = survey::PingClock::kTopsideHeader;
            }
        };
        while (in) {
            in.read(reinterpret_cast<char*>(buf.data()), static_cast<std::streamsize>(buf.size()));
            const auto got = static_cast<std::size_t>(in.gcount());
            if (got == 0) break;
            into.counts.bytes += static_cast<std::int64_t>(got);
            s.deltat->Push(ByteSpan(buf.data(), got));
            drain();
        }
        while (auto sk = s.deltat->Flush()) {
            skipped(*sk);
            drain();
        }
        detail::RecordSpan(into, path, mark);
        if (skip_events > kMaxSkipWarnings) {
            into.warnings.push_back(path + ": " + std::to_string(skip_events - kMaxSkipWarnings) +
                                    " more damaged places, " + std::to_string(skipped_unwarned) +
                                    " bytes skipped (raw_skipped_bytes counts them all)");
        }
        ++into.counts.files;
    }
    into.pings_from_raw = true;
    return Ok{};
}

Expected<std::vector<std::string>> ExpandInputs(const std::vector<std::string>& inputs) {
    std::vector<std::string> out;
    for (const std::string& in : inputs) {
        std::error_code ec;
        if (fs::is_directory(in, ec)) {
            std::vector<std::string> files;
            for (const auto& e : fs::directory_iterator(in, ec)) {
                if (!e.is_regular_file()) continue;
                std::string ext = e.path().extension().string();
                for (char& ch : ext)
                    ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
                if (ext == ".lcmlog" || ext == ".83p" || ext == ".gps" || ext == ".asc" ||
                    ext == ".bin" || ext == ".xtf") {
                    files.push_back(e.path().string());
                }
            }
            if (ec) return Error{in + ": cannot list: " + ec.message()};
            std::sort(files.begin(), files.end());
            if (files.empty())
                return Error{in + ": no .lcmlog, .83P, .xtf or NovAtel files in this folder"};
            out.insert(out.end(), files.begin(), files.end());
        } else if (fs::is_regular_file(in, ec)) {
            out.push_back(in);
        } else {
            return Error{in + ": no such file or folder"};
        }
    }
    return out;
}

Expected<IngestResult> IngestFiles(const std::vector<std::string>& files,
                                   const IngestConfig& config,
                                   const ProgressCallback& progress) {
    std::vector<std::string> lcm, p83, xtf, novatel, skipped;
    for (const auto& f : files) {
        switch (Sniff(f)) {
            case FileKind::kLcm:
                lcm.push_back(f);
                break;
            case FileKind::k83P:
                p83.push_back(f);
                break;
            case FileKind::kXtf:
                xtf.push_back(f);
                break;
            case FileKind::kNovatel:
                novatel.push_back(f);
                break;
            case FileKind::kUnknown:
                // An empty segment (e.g. created while the disk was full) holds nothing to
                // lose: it is skipped and said so, and the other files are read.
                skipped.push_back(f + ": empty or too short to be a log file, skipped");
                break;
        }
    }
    if (lcm.empty() && p83.empty() && xtf.empty() && novatel.empty()) {
        return Error{files.empty() ? std::string("no input files")
                                   : files.front() + (files.size() > 1 ? " and the others" : "") +
                                         ": empty or too short to be log files"};
    }
    IngestResult r;
    if (!lcm.empty()) {
        auto a = IngestLcmLogs(lcm, config, progress);
        if (!a) return a.error();
        r = std::move(*a);
    }
    if (!novatel.empty()) {
        auto b = IngestNovatelFiles(novatel, config);
        if (!b) return b.error();
        r.nav.samples.insert(r.nav.samples.end(), b->nav.samples.begin(), b->nav.samples.end());
        r.nav.stddevs.insert(r.nav.stddevs.end(), b->nav.stddevs.begin(), b->nav.stddevs.end());
        if (b->nav.leap_seconds >= 0) r.nav.leap_seconds = b->nav.leap_seconds;
        // Every count, not a chosen few: the merged result is re-finished below, which
        // recomputes the sample totals and adds the duplicates found across inputs.
        r.counts += b->counts;
        r.files.insert(r.files.end(), b->files.begin(), b->files.end());
        r.conflict_times.insert(
            r.conflict_times.end(), b->conflict_times.begin(), b->conflict_times.end());
        r.ins_windows.insert(r.ins_windows.end(), b->ins_windows.begin(), b->ins_windows.end());
        r.warnings.insert(r.warnings.end(), b->warnings.begin(), b->warnings.end());
        r.nav_from_raw = true;
    }
    // Pings of a log (GPS time) and of .83P files (the sonar's own clock) are on two clocks
    // until the sonar clock is found: their gaps say nothing about sessions together.
    const bool pings_on_one_clock = r.pings.pings.empty() || p83.empty();
    if (!p83.empty()) {
        if (auto s = Ingest83PFiles(p83, config, r.nav.leap_seconds, r); !s) return s.error();
    }
    if (!xtf.empty()) {
        if (auto s = IngestXtfFiles(xtf, r.nav.leap_seconds, r); !s) return s.error();
    }
    r.counts.files_skipped += static_cast<std::int64_t>(skipped.size());
    r.warnings.insert(r.warnings.end(), skipped.begin(), skipped.end());
    Finish(r);
    // Two recordings in one set of inputs are never merged or dropped in silence.
    if (auto c = detail::CheckConflicts(r); !c) return c.error();
    if (auto c = detail::SplitSessions(r, config, pings_on_one_clock); !c) return c.error();
    detail::ReportGaps(r, config);
    // The INS status rule was applied by each reader (IngestLcmLogs, IngestNovatelFiles), to
    // every message it read.
    std::stable_sort(r.ins_windows.begin(), r.ins_windows.end(), [](const auto& a, const auto& b) {
        return a.first_utime < b.first_utime;
    });
    SetTotals(r);
    // Damage is not only counted in the summary: the run says so where it is read.
    const IngestCounts& c = r.counts;
    if (c.corrupt_events + c.length_repairs + c.truncated_events + c.decode_failures > 0 ||
        c.resync_bytes > 0) {
        r.warnings.push_back(
            "damaged input: " + std::to_string(c.corrupt_events) + " corrupt event headers, " +
            std::to_string(c.resync_bytes) + " bytes skipped to resynchronise, " +
            std::to_string(c.length_repairs) + " event lengths repaired, " +
            std::to_string(c.truncated_events) + " events cut at a file end, " +
            std::to_string(c.decode_failures) + " events that do not decode (skipped)");
    }
    return r;
}

}  // namespace pitmap::proc::io
