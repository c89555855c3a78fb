// SPDX-License-Identifier: MIT
#include "processor/io/ingest_sessions.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <set>
#include <vector>

#include "common/gps_time.hpp"
#include "common/protocol/novatel/messages.hpp"

namespace pitmap::proc::io::detail {

namespace {

namespace nv = protocol::novatel;
using survey::NavSample;
using survey::NavStdDev;
using survey::PingHeader;

std::string Fmt(const char* fmt, double v) {
    char b[64];
    std::snprintf(b, sizeof(b), fmt, v);
    return b;
}

// "2026-06-15T09:00:00Z" for a GPS time; pings of .83P files are on the sonar's own clock.
std::string Utc(std::int64_t utime_gps) {
    return FormatUnixIso8601(UnixFromGps(utime_gps));
}

std::string Duration(double s) {
    if (s >= 0.95 * 86400) return Fmt("%.1f days", s / 86400);
    if (s >= 2 * 3600) return Fmt("%.1f h", s / 3600);
    if (s >= 120) return Fmt("%.1f min", s / 60);
    return Fmt("%.1f s", s);
}

// Horizontal distance between two geodetic positions, m (equirectangular: the jumps it judges
// are hundreds of metres to kilometres).
double DistanceM(const Geodetic& a, const Geodetic& b) {
    constexpr double kR = 6371000.0, kDeg = 3.14159265358979323846 / 180.0;
    const double x = (b.longitude_deg - a.longitude_deg) * kDeg *
                     std::cos(0.5 * (a.latitude_deg + b.latitude_deg) * kDeg);
    const double y = (b.latitude_deg - a.latitude_deg) * kDeg;
    return kR * std::hypot(x, y);
}

std::string FileList(const std::vector<std::string>& files) {
    std::string s;
    for (std::size_t i = 0; i < files.size() && i < 4; ++i) s += (i ? ", " : "") + files[i];
    if (files.size() > 4) s += " and " + std::to_string(files.size() - 4) + " more";
    return s.empty() ? std::string("(no file)") : s;
}

struct Session {
    std::size_t begin = 0, end = 0;  // index range in the series
    std::int64_t first = 0, last = 0;
    std::string why_split;  // what separates it from the previous session
};

// Sessions of a time-sorted series: split at gaps over gap_s and (with positions) at jumps.
template <class T, class Pos>
std::vector<Session> FindSessions(const std::vector<T>& v,
                                  const IngestConfig& c,
                                  const Pos& position) {
    std::vector<Session> out;
    if (v.empty()) return out;
    const auto gap_us = static_cast<std::int64_t>(c.session_gap_s * 1e6);
    Session cur{0, 0, v.front().utime_gps, v.front().utime_gps, ""};
    for (std::size_t i = 1; i < v.size(); ++i) {
        const std::int64_t dt = v[i].utime_gps - v[i - 1].utime_gps;
        std::string why;
        if (dt > gap_us) {
            why = Duration(static_cast<double>(dt) * 1e-6) + " later";
        } else if (const auto d = position(v[i - 1], v[i]); d) {
            const double dt_s = std::max(static_cast<double>(dt) * 1e-6, 1e-3);
            if (*d > 50.0 && *d / dt_s > c.max_session_speed_mps) {
                why = Fmt("%.1f km away", *d / 1000.0) + " within " +
                      Duration(static_cast<double>(dt) * 1e-6);
            }
        }
        if (!why.empty()) {
            cur.end = i;
            out.push_back(cur);
            cur = Session{i, i, v[i].utime_gps, v[i].utime_gps, why};
        }
        cur.last = v[i].utime_gps;
    }
    cur.end = v.size();
    out.push_back(cur);
    return out;
}

std::vector<std::string> FilesIn(const IngestResult& r, std::int64_t a, std::int64_t b, bool nav) {
    std::vector<std::string> f;
    for (const auto& s : r.files) {
        const std::int64_t n = nav ? s.nav_samples : s.pings;
        const std::int64_t x0 = nav ? s.nav_first : s.ping_first;
        const std::int64_t x1 = nav ? s.nav_last : s.ping_last;
        if (n > 0 && x0 <= b && x1 >= a) f.push_back(s.path);
    }
    return f;
}

std::string DescribeSessions(const IngestResult& r,
                             const std::vector<Session>& sessions,
                             bool nav) {
    std::string s;
    const bool sonar_clock = !nav && r.pings.clock == survey::PingClock::kTopsideHeader;
    for (std::size_t i = 0; i < sessions.size(); ++i) {
        const Session& x = sessions[i];
        s += "\n  " + std::string(nav ? "navigation" : "pings") + " session " +
             std::to_string(i + 1) + (x.why_split.empty() ? "" : " (" + x.why_split + ")") + ": " +
             Utc(x.first) + " .. " + Utc(x.last) +
             (sonar_clock ? " on the sonar's own clock" : "") + ", " +
             std::to_string(x.end - x.begin) + (nav ? " samples" : " pings") + ", from " +
             FileList(FilesIn(r, x.first, x.last, nav));
    }
    return s;
}

enum class InsClass { kGood, kDegraded, kNotNavigating };

InsClass Classify(std::int32_t status) {
    switch (status) {
        case -1:  // a source without status (e.g. decoded channels of an older daemon)
        case static_cast<std::int32_t>(nv::InsStatus::kSolutionGood):
            return InsClass::kGood;
        case static_cast<std::int32_t>(nv::InsStatus::kHighVariance):
        case static_cast<std::int32_t>(nv::InsStatus::kSolutionFree):
        case static_cast<std::int32_t>(nv::InsStatus::kAlignmentComplete):
            return InsClass::kDegraded;
        default:
            return InsClass::kNotNavigating;
    }
}

std::string StatusName(std::int32_t status) {
    const std::string_view n = nv::ToString(static_cast<nv::InsStatus>(status));
    return n.empty() ? "INS status " + std::to_string(status) : std::string(n);
}

float Floor(float v, double floor) {
    return std::isfinite(v) ? std::max(v, static_cast<float>(floor)) : static_cast<float>(floor);
}

// Keeps the pings of one session (their beams, intensities and beam angles rebuilt).
void KeepPings(survey::PingSeries& pings, const Session& s) {
    survey::PingSeries out;
    out.clock = pings.clock;
    const bool with = pings.has_intensities();
    const bool with_angles = pings.has_beam_angles();
    for (std::size_t k = s.begin; k < s.end; ++k) {
        PingHeader h = pings.pings[k];
        const std::uint32_t from = h.beam_offset;
        h.beam_offset = static_cast<std::uint32_t>(out.range_counts.size());
        const auto b = pings.range_counts.begin() + from;
        out.range_counts.insert(out.range_counts.end(), b, b + h.num_beams);
        if (with) {
            const auto bi = pings.intensities.begin() + from;
            out.intensities.insert(out.intensities.end(), bi, bi + h.num_beams);
        }
        if (with_angles) {
            const auto ba = pings.beam_angles_deg.begin() + from;
            out.beam_angles_deg.insert(out.beam_angles_deg.end(), ba, ba + h.num_beams);
        }
        out.pings.push_back(h);
    }
    pings = std::move(out);
}

}  // namespace

SpanMark MarkSpan(const IngestResult& r) {
    return {r.nav.samples.size(), r.pings.pings.size()};
}

void RecordSpan(IngestResult& r, const std::string& path, const SpanMark& mark) {
    InputFileSpan f;
    f.path = path;
    for (std::size_t i = mark.nav; i < r.nav.samples.size(); ++i) {
        const std::int64_t t = r.nav.samples[i].utime_gps;
        f.nav_first = f.nav_samples == 0 ? t : std::min(f.nav_first, t);
        f.nav_last = f.nav_samples == 0 ? t : std::max(f.nav_last, t);
        ++f.nav_samples;
    }
    for (std::size_t i = mark.pings; i < r.pings.pings.size(); ++i) {
        const std::int64_t t = r.pings.pings[i].utime_gps;
        f.ping_first = f.pings == 0 ? t : std::min(f.ping_first, t);
        f.ping_last = f.pings == 0 ? t : std::max(f.ping_last, t);
        ++f.pings;
    }
    r.files.push_back(std::move(f));
}

void TakeSpans(IngestResult& r, const IngestResult& from, bool nav, bool pings) {
    for (auto& f : r.files) {
        for (const auto& g : from.files) {
            if (g.path != f.path) continue;
            if (nav) {
                f.nav_first = g.nav_first;
                f.nav_last = g.nav_last;
                f.nav_samples = g.nav_samples;
            }
            if (pings) {
                f.ping_first = g.ping_first;
                f.ping_last = g.ping_last;
                f.pings = g.pings;
            }
            break;
        }
    }
}

Status CheckConflicts(IngestResult& r) {
    if (r.conflict_times.empty()) return Ok{};
    // A few: a logger's clock that stepped back (the pings are both kept, a nav sample is
    // dropped), said. Many: two recordings.
    const auto many = [](std::int64_t conflicts, std::size_t items) {
        return conflicts > std::max<std::int64_t>(10, static_cast<std::int64_t>(items) / 100);
    };
    if (!many(r.counts.nav_conflicts, r.nav.samples.size()) &&
        !many(r.counts.ping_conflicts, r.pings.pings.size())) {
        r.warnings.push_back(
            std::to_string(r.counts.nav_conflicts) + " navigation samples and " +
            std::to_string(r.counts.ping_conflicts) +
            " pings share their time stamp with a different one (a logger's clock that stepped "
            "back?), first at " +
            Utc(*std::min_element(r.conflict_times.begin(), r.conflict_times.end())) +
            ": of two samples the first is kept, both pings are kept");
        return Ok{};
    }
    const auto [lo, hi] = std::minmax_element(r.conflict_times.begin(), r.conflict_times.end());
    std::set<std::string> files;
    for (const auto& f : r.files) {
        for (const std::int64_t t : r.conflict_times) {
            if ((f.nav_samples > 0 && t >= f.nav_first && t <= f.nav_last) ||
                (f.pings > 0 && t >= f.ping_first && t <= f.ping_last)) {
                files.insert(f.path);
                break;
            }
        }
    }
    return Error{
        "ingest: " + std::to_string(r.counts.nav_conflicts) + " navigation samples and " +
        std::to_string(r.counts.ping_conflicts) + " pings are held twice with different content, " +
        Utc(*lo) + " .. " + Utc(*hi) + ", in " + FileList({files.begin(), files.end()}) +
        ": two recordings over the same times (two surveys on one clock?), not a repeated "
        "message (those are dropped as duplicates). Nothing is merged or dropped: process each "
        "recording on its own (pitmap run FILES --out P)"};
}

Status SplitSessions(IngestResult& r, const IngestConfig& c, bool pings_on_one_clock) {
    const auto nav_sessions =
        FindSessions(r.nav.samples, c, [](const NavSample& a, const NavSample& b) {
            return std::optional<double>(DistanceM(a.position, b.position));
        });
    const auto ping_sessions =
        pings_on_one_clock
            ? FindSessions(r.pings.pings,
                           c,
                           [](const PingHeader&, const PingHeader&) -> std::optional<double> {
                               return std::nullopt;
                           })
            : std::vector<Session>{};
    const std::size_t n = std::max(nav_sessions.size(), ping_sessions.size());
    r.counts.sessions = static_cast<std::int64_t>(n);
    if (n <= 1) {
        if (c.session > 1)
            return Error{"ingest.session " + std::to_string(c.session) +
                         ": the inputs hold one recording"};
        return Ok{};
    }
    const std::string list =
        DescribeSessions(r, nav_sessions, true) + DescribeSessions(r, ping_sessions, false);
    if (c.session < 1 || static_cast<std::size_t>(c.session) > n) {
        return Error{"ingest: the inputs hold " + std::to_string(n) +
                     " recordings (sessions separated by more than " + Duration(c.session_gap_s) +
                     " or a jump over " + Fmt("%.0f", c.max_session_speed_mps) + " m/s):" + list +
                     "\nThey are not merged into one survey: process each on its own (pitmap run "
                     "FILES --out P), or choose one with ingest.session: N in the config"};
    }
    const auto pick = static_cast<std::size_t>(c.session - 1);
    if (nav_sessions.size() > 1) {
        const Session& s = nav_sessions.at(std::min(pick, nav_sessions.size() - 1));
        std::vector<NavSample> kept(r.nav.samples.begin() + static_cast<std::ptrdiff_t>(s.begin),
                                    r.nav.samples.begin() + static_cast<std::ptrdiff_t>(s.end));
        r.nav.samples = std::move(kept);
        std::vector<NavStdDev> sd;
        for (const auto& x : r.nav.stddevs) {
            if (x.utime_gps >= s.first - 5'000'000 && x.utime_gps <= s.last + 5'000'000)
                sd.push_back(x);
        }
        r.nav.stddevs = std::move(sd);
    }
    // Pings on GPS time (logged by pitmap-acqd) belong to the navigation session they fall in;
    // pings on the sonar's own clock can only be told apart by their own gaps.
    const bool gps_pings = r.pings.clock != survey::PingClock::kTopsideHeader;
    if (gps_pings && nav_sessions.size() > 1) {
        const Session& ns = nav_sessions.at(std::min(pick, nav_sessions.size() - 1));
        Session s;
        s.begin = static_cast<std::size_t>(
            std::lower_bound(r.pings.pings.begin(),
                             r.pings.pings.end(),
                             ns.first,
                             [](const PingHeader& h, std::int64_t t) { return h.utime_gps < t; }) -
            r.pings.pings.begin());
        s.end = static_cast<std::size_t>(
            std::upper_bound(r.pings.pings.begin(),
                             r.pings.pings.end(),
                             ns.last,
                             [](std::int64_t t, const PingHeader& h) { return t < h.utime_gps; }) -
            r.pings.pings.begin());
        KeepPings(r.pings, s);
    } else if (ping_sessions.size() > 1) {
        KeepPings(r.pings, ping_sessions.at(std::min(pick, ping_sessions.size() - 1)));
    }
    r.warnings.push_back("ingest.session " + std::to_string(c.session) + " of " +
                         std::to_string(n) + " recordings kept; the others are left out:" + list);
    return Ok{};
}

void ApplyInsStatusRule(IngestResult& r, const IngestConfig& c) {
    std::vector<NavSample>& v = r.nav.samples;
    std::vector<char> keep(v.size(), 1);
    r.ins_windows.clear();
    for (std::size_t i = 0; i < v.size();) {
        const InsClass k = Classify(v[i].ins_status);
        if (k == InsClass::kGood) {
            ++i;
            continue;
        }
        InsStatusWindow w;
        w.navigating = k == InsClass::kDegraded;
        w.dropped = !w.navigating || c.require_good_ins;
        w.first_utime = v[i].utime_gps;
        std::set<std::string> names;
        std::size_t j = i;
        for (; j < v.size() && Classify(v[j].ins_status) == k; ++j) {
            names.insert(StatusName(v[j].ins_status));
            keep[j] = w.dropped ? 0 : 1;
        }
        w.last_utime = v[j - 1].utime_gps;
        w.samples = static_cast<std::int64_t>(j - i);
        for (const auto& nm : names) w.statuses += (w.statuses.empty() ? "" : ", ") + nm;
        r.ins_windows.push_back(w);
        i = j;
    }
    for (const auto& w : r.ins_windows) {
        (w.navigating ? r.counts.nav_degraded : r.counts.nav_not_navigating) += w.samples;
        if (w.dropped) r.counts.nav_not_good += w.samples;
    }
    if (r.ins_windows.empty()) return;
    std::size_t out = 0;
    for (std::size_t i = 0; i < v.size(); ++i) {
        if (keep[i]) v[out++] = v[i];
    }
    v.resize(out);
    // Degraded samples kept: their stddevs raised to the floors (records added at 1 Hz where
    // the window has none), so that SLAM and the TPU weigh them as degraded.
    std::vector<NavStdDev>& sd = r.nav.stddevs;
    for (const auto& w : r.ins_windows) {
        if (w.dropped) continue;
        bool any = false;
        for (auto& x : sd) {
            if (x.utime_gps < w.first_utime || x.utime_gps > w.last_utime) continue;
            any = true;
            x.north_m = Floor(x.north_m, c.degraded_ins_sigma_m);
            x.east_m = Floor(x.east_m, c.degraded_ins_sigma_m);
            x.up_m = Floor(x.up_m, c.degraded_ins_sigma_m);
            x.roll_deg = Floor(x.roll_deg, c.degraded_ins_sigma_deg);
            x.pitch_deg = Floor(x.pitch_deg, c.degraded_ins_sigma_deg);
            x.yaw_deg = Floor(x.yaw_deg, c.degraded_ins_sigma_deg);
        }
        if (any) continue;
        const auto m = static_cast<float>(c.degraded_ins_sigma_m);
        const auto d = static_cast<float>(c.degraded_ins_sigma_deg);
        for (std::int64_t t = w.first_utime;; t += 1'000'000) {
            const std::int64_t at = std::min(t, w.last_utime);
            sd.push_back({at, m, m, m, d, d, d});
            if (at == w.last_utime) break;
        }
    }
    std::stable_sort(sd.begin(), sd.end(), [](const auto& a, const auto& b) {
        return a.utime_gps < b.utime_gps;
    });
    constexpr std::size_t kListed = 10;
    for (std::size_t i = 0; i < r.ins_windows.size() && i < kListed; ++i) {
        const auto& w = r.ins_windows[i];
        const double len = static_cast<double>(w.last_utime - w.first_utime) * 1e-6;
        std::string what;
        if (!w.navigating) {
            what = "no navigation solution: dropped (pings there are not georeferenced)";
        } else if (w.dropped) {
            what = "degraded solution: dropped (ingest.require_good_ins)";
        } else {
            what = "degraded solution: kept with its sigmas raised to at least " +
                   Fmt("%.2f", c.degraded_ins_sigma_m) + " m and " +
                   Fmt("%.2f", c.degraded_ins_sigma_deg) +
                   " deg (ingest.degraded_ins_sigma_m/_deg; ingest.require_good_ins drops it)";
        }
        r.warnings.push_back("INS status " + w.statuses + " from " + Utc(w.first_utime) + " for " +
                             Duration(len) + " (" + std::to_string(w.samples) +
                             " samples): " + what);
    }
    if (r.ins_windows.size() > kListed) {
        r.warnings.push_back(std::to_string(r.ins_windows.size() - kListed) +
                             " more windows with the INS status not INS_SOLUTION_GOOD");
    }
}

void ReportGaps(IngestResult& r, const IngestConfig& c) {
    const auto gap_us = static_cast<std::int64_t>(c.report_gap_s * 1e6);
    constexpr int kListed = 5;
    const auto report = [&](const auto& v, std::int64_t& count, const char* what, bool own_clock) {
        std::vector<std::string> listed;
        for (std::size_t i = 1; i < v.size(); ++i) {
            const std::int64_t dt = v[i].utime_gps - v[i - 1].utime_gps;
            if (dt <= gap_us) continue;
            ++count;
            if (static_cast<int>(listed.size()) < kListed) {
                listed.push_back(Duration(static_cast<double>(dt) * 1e-6) + " after " +
                                 Utc(v[i - 1].utime_gps));
            }
        }
        if (count == 0) return;
        std::string s = std::to_string(count) + " gap(s) over " + Fmt("%.1f", c.report_gap_s) +
                        " s in the " + what + (own_clock ? " (on the sonar's own clock)" : "") +
                        ": ";
        for (std::size_t i = 0; i < listed.size(); ++i) s += (i ? "; " : "") + listed[i];
        if (count > kListed) s += "; ...";
        r.warnings.push_back(s);
    };
    report(r.nav.samples, r.counts.nav_gaps, "navigation", false);
    report(r.pings.pings,
           r.counts.ping_gaps,
           "pings",
           r.pings.clock == survey::PingClock::kTopsideHeader);
}

}  // namespace pitmap::proc::io::detail
