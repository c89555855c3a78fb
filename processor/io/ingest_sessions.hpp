// SPDX-License-Identifier: MIT
// Internal to processor/io ingest: what the merged series of all inputs must be checked for
// before they are one survey (IngestConfig in ingest.hpp documents the settings):
//   - conflicts: one time held twice with different content (SortAndDeduplicate finds them) is
//     not a repeated message: many are two recordings (an error naming the files that hold
//     those times), a few a logger's clock step (a warning);
//   - sessions: a gap longer than session_gap_s, or a jump no vehicle makes, separates two
//     recordings; more than one is an error naming the files of each, unless ingest.session
//     picks one (the others' samples and pings are then left out, and said);
//   - the INS status rule (not navigating: dropped; degraded: kept, sigmas raised), with its
//     windows listed in IngestResult::ins_windows and the warnings;
//   - gaps within the session longer than report_gap_s, as warnings.
// The per-file spans (MarkSpan before a file, RecordSpan after it) name the files.
#pragma once

#include <cstddef>
#include <string>

#include "common/result.hpp"
#include "processor/io/ingest.hpp"

namespace pitmap::proc::io::detail {

struct SpanMark {
    std::size_t nav = 0, pings = 0;  // series sizes before the file
};
SpanMark MarkSpan(const IngestResult& r);
// Appends the span of what was added since `mark` to r.files.
void RecordSpan(IngestResult& r, const std::string& path, const SpanMark& mark);
// The second (raw) pass of LCM ingest replaced the nav and/or the pings: their spans too.
void TakeSpans(IngestResult& r, const IngestResult& from, bool nav, bool pings);

// Many conflicts (over 1 % of the samples or pings, and over 10) are an error naming the
// files; a few are a warning.
Status CheckConflicts(IngestResult& r);
// `pings_on_one_clock` false: the pings come from sources on different clocks (a log and .83P
// files), whose gaps between each other mean nothing; only the navigation is split then.
Status SplitSessions(IngestResult& r, const IngestConfig& config, bool pings_on_one_clock = true);
void ApplyInsStatusRule(IngestResult& r, const IngestConfig& config);
void ReportGaps(IngestResult& r, const IngestConfig& config);

}  // namespace pitmap::proc::io::detail
