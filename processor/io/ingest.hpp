// SPDX-License-Identifier: MIT
// Ingest: LCM logs (pitmap-acqd, pitmap-sim) and vendor files (.83P, NovAtel binary/ASCII) into
// the NavSeries and PingSeries of processor/survey/series.hpp, in GPS time, with counts of
// everything skipped.
//
// LCM logs: files are read in the order given (rotated segments sort by name). Decoded channels
// (INS_PVA_<ID>, INS_STDDEV_<ID>, GPS_TIME_<ID>, MULTIBEAM_PING_<ID>) are preferred; the raw
// channels (raw_bytes_t, recognised by decoding, with `protocol` "novatel" / "deltat_83p") are
// re-decoded with common/protocol when `source` is kRaw, or in kAuto for a stream (navigation
// or sonar) that has no decoded channel in the logs. A re-decoded ping gets the time the daemon
// gave it live: the same rule and clock model (common/clock/ping_time.hpp), fed the receive
// times its RAW_<ID> chunks logged, one model per sonar channel.
// .83P files carry only the topside PC's clock: utime_gps = header time (read as UTC) + GPS-UTC
// (from a NovAtel TIME log when one is given, else the leap-second table) - sonar_clock_offset_s,
// where sonar_clock_offset_s = sonar clock - UTC (> 0: the sonar clock runs ahead of UTC;
// common/vehicle.hpp); 0 when not known (the pipeline then finds the clock, calib/sonar_clock).
// Failure model: unreadable files are errors naming the path; bad bytes and bad events are
// counted, never fatal.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "common/clock/clock_model.hpp"
#include "common/progress.hpp"
#include "common/result.hpp"
#include "processor/survey/series.hpp"

namespace pitmap::proc::io {

enum class IngestSource { kAuto = 0, kDecoded, kRaw };
const char* ToString(IngestSource s);
bool ParseIngestSource(const std::string& text, IngestSource& out);

struct IngestConfig {
    IngestSource source = IngestSource::kAuto;  // decoded channels, raw re-decoding, or auto
    std::string nav_channel_id;    // channel id (e.g. "novatel_com1"); "" = every INS channel
    std::string sonar_channel_id;  // e.g. "deltat_udp"; "" = every sonar channel
    // .83P files: sonar (header) clock minus UTC, s, subtracted from header times (> 0 = the
    // sonar clock runs ahead). Known (given by the user, the config or the vehicle file):
    // checked against the 83P headers; else searched for (processor/calib/sonar_clock.hpp).
    double sonar_clock_offset_s = 0;
    bool sonar_clock_offset_known = false;
    // INS status (NovAtel INSPVA/INSPVAX): samples in no navigating state (INACTIVE, ALIGNING,
    // the WAITING/DETERMINING/INITIALIZING states, MOTION_DETECT, unknown values) are no
    // solution and are always dropped; degraded ones (HIGH_VARIANCE, SOLUTION_FREE,
    // ALIGNMENT_COMPLETE) are kept with their standard deviations raised to at least
    // degraded_ins_sigma_m / _deg, so that SLAM and the TPU weigh them as what they are;
    // require_good_ins drops them too. Every such window is counted, listed and a georef gate.
    bool require_good_ins = false;        // also drop degraded samples (only SOLUTION_GOOD kept)
    double degraded_ins_sigma_m = 0.5;    // floor of a degraded sample's position sigma
    double degraded_ins_sigma_deg = 0.2;  // ... and of its attitude sigmas
    // Sessions: a gap longer than session_gap_s in the navigation or in the pings, or a jump
    // faster than max_session_speed_mps, separates two recordings (surveys). More than one is
    // an error naming the files of each, unless `session` picks one (1-based; 0 = there must be
    // one). Gaps longer than report_gap_s within a session are reported.
    double session_gap_s = 600;
    double max_session_speed_mps = 20;
    double report_gap_s = 2.0;
    int session = 0;
    // Re-decoded raw 83P: the sonar clock model; must equal the daemon's (its `clock:`
    // settings, e.g. sonar_header_resolution_us) for re-decoded pings to get its times.
    clock::SonarClockConfig sonar_clock{};

    std::vector<std::string> Validate() const;
};

struct IngestCounts {
    std::int64_t files = 0;
    std::int64_t bytes = 0;
    std::int64_t events = 0;
    std::int64_t corrupt_events = 0;  // impossible event headers (resynchronised)
    std::int64_t resync_bytes = 0;
    std::int64_t truncated_events = 0;  // cut by the end of a file
    std::int64_t length_repairs = 0;    // event lengths that did not land on the next event
    std::int64_t files_skipped = 0;     // empty or too short to be a log
    std::int64_t decode_failures = 0;   // events whose lcmtype did not decode
    std::int64_t nav_samples = 0;
    std::int64_t nav_without_time = 0;    // utime_gps = 0
    std::int64_t nav_not_good = 0;        // dropped for their INS status (either reason below)
    std::int64_t nav_not_navigating = 0;  // INS in no navigating state (always dropped)
    std::int64_t nav_degraded = 0;        // degraded INS status (kept, sigmas raised)
    std::int64_t nav_conflicts = 0;       // one time, different content (two recordings)
    std::int64_t ping_conflicts = 0;
    std::int64_t nav_gaps = 0;  // gaps over report_gap_s within the session
    std::int64_t ping_gaps = 0;
    std::int64_t sessions = 0;  // recordings found in the inputs
    std::int64_t nav_duplicates = 0;
    std::int64_t stddev_samples = 0;
    std::int64_t pings = 0;
    std::int64_t pings_without_time = 0;
    std::int64_t pings_bad = 0;  // no beams, over-long, undecodable 83P
    std::int64_t ping_duplicates = 0;
    std::int64_t raw_chunks_decoded = 0;
    std::int64_t raw_skipped_bytes = 0;  // framer skips in re-decoded raw streams
    std::int64_t raw_decode_errors = 0;
    std::map<std::string, std::int64_t> events_by_channel;

    // Adds every count of `o` (used when the results of several inputs are merged).
    IngestCounts& operator+=(const IngestCounts& o);
};

// A run of INS samples whose status is not INS_SOLUTION_GOOD (first and last sample time).
struct InsStatusWindow {
    std::int64_t first_utime = 0, last_utime = 0;
    bool navigating = true;  // false: no solution (dropped)
    bool dropped = false;    // removed from the series (not navigating, or require_good_ins)
    std::int64_t samples = 0;
    std::string statuses;  // the status names seen, e.g. "INS_HIGH_VARIANCE"
};

// What one input file held (time spans of the samples and pings read from it; 0 = none).
struct InputFileSpan {
    std::string path;
    std::int64_t nav_first = 0, nav_last = 0, nav_samples = 0;
    std::int64_t ping_first = 0, ping_last = 0, pings = 0;
};

struct IngestResult {
    survey::NavSeries nav;
    survey::PingSeries pings;
    IngestCounts counts;
    bool nav_from_raw = false;
    bool pings_from_raw = false;
    std::string message;
    std::vector<std::string>
        warnings;  // files skipped and why: print them, keep them in the summary
    // What a vendor file did not say and had to be assumed (XTF: sigmas, height datum, ...):
    // print them, keep them in the summary.
    std::vector<std::string> assumed;
    std::vector<InputFileSpan> files;          // per input file, in the order read
    std::vector<InsStatusWindow> ins_windows;  // INS status not good, in time order
    std::vector<std::int64_t> conflict_times;  // nav and ping times held twice, differently
};

// Reads LCM log files in order. An empty list or an unreadable file is an error.
Expected<IngestResult> IngestLcmLogs(const std::vector<std::string>& paths,
                                     const IngestConfig& config,
                                     const ProgressCallback& progress = {});

// Reads NovAtel binary or ASCII log files (any mix of messages; INS ones are kept).
Expected<IngestResult> IngestNovatelFiles(const std::vector<std::string>& paths,
                                          const IngestConfig& config);

// Reads .83P files; `leap_seconds` < 0 uses the table. Adds to `into`.
Status Ingest83PFiles(const std::vector<std::string>& paths,
                      const IngestConfig& config,
                      int leap_seconds,
                      IngestResult& into);

// Expands directories (their *.lcmlog, *.83P, *.xtf, *.gps/*.asc/*.bin files, sorted by name) and
// keeps files as given. Fails for a path that does not exist.
Expected<std::vector<std::string>> ExpandInputs(const std::vector<std::string>& inputs);

// Dispatches by content: LCM logs, .83P files, XTF files (processor/io/xtf.hpp), NovAtel files;
// sorts and deduplicates.
Expected<IngestResult> IngestFiles(const std::vector<std::string>& files,
                                   const IngestConfig& config,
                                   const ProgressCallback& progress = {});

}  // namespace pitmap::proc::io
