// SPDX-License-Identifier: MIT
// The edit log: the hand edits of soundings (issue 35), P/edits.json. `pitmap edit` appends to
// it; every stage command reads it again and applies it on top of the automatic statuses
// (survey/sounding_status.hpp: a manual reject or restore wins over the cleaning, a restore
// also over the range gate and the spike filter). It survives re-runs: georef and run never
// remove it, and it names the survey it belongs to, so that it is never applied to another.
//
// Format (JSON):
//   {"pitmap_edit_log": 1,
//    "survey": {"pings": N, "soundings": M, "fingerprint": "16 hex digits"},
//    "edits": [{"action": "reject" | "restore", "at": "UTC ISO 8601", "source": "...",
//               "runs": [[ping, first_beam, count], ...]}, ...]}
// `ping` is the ping's index in the survey's ping series (time order), `first_beam` and `count`
// a run of consecutive beams of that ping. The fingerprint is FNV-1a (64 bit) over every
// ping's 83P ping number and beam count, in order: the same inputs give the same survey
// whatever the clock correction or the calibration did. Edits apply in order (a later one
// wins); undo is removing the last edit.
// Failure model: a file that is not JSON, not an edit log, of another format version, of
// another survey, or whose runs fall outside the survey is an error naming the file and the
// problem; nothing of it is applied.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/survey/series.hpp"
#include "processor/survey/sounding_status.hpp"

namespace pitmap::proc::survey {

inline constexpr const char* kEditLogFileName = "edits.json";
inline constexpr int kEditLogVersion = 1;

// Which survey an edit log belongs to.
struct SurveyIdentity {
    std::uint64_t pings = 0;
    std::uint64_t soundings = 0;
    std::string fingerprint;  // 16 lower-case hex digits
    bool operator==(const SurveyIdentity& o) const {
        return pings == o.pings && soundings == o.soundings && fingerprint == o.fingerprint;
    }
};
SurveyIdentity IdentityOf(const survey::PingSeries& pings);

// A run of consecutive beams of one ping.
struct SoundingRun {
    std::uint32_t ping = 0;
    std::uint32_t first_beam = 0;
    std::uint32_t count = 0;
};

struct Edit {
    survey::ManualEdit action = survey::ManualEdit::kReject;  // kReject or kRestore
    std::string at_utc;                                       // when it was made
    std::string source;                                       // "pitmap edit", a script, ...
    std::vector<SoundingRun> runs;
};

struct EditLog {
    SurveyIdentity survey;
    std::vector<Edit> edits;
    std::size_t num_soundings() const;  // over every edit's runs
};

// Runs of the soundings `index` (indices into the range counts, any order, repeats allowed).
std::vector<SoundingRun> RunsOf(const survey::PingSeries& pings, std::vector<std::uint32_t> index);

// Reads an edit log. A missing file is an error too (the caller checks for one first).
Expected<EditLog> ReadEditLog(const std::string& path);
// Writes it (under a temporary name, renamed into place).
Status WriteEditLog(const std::string& path, const EditLog& log);

// The manual edit of every sounding of `pings` (index = beam_offset + beam; ManualEdit codes):
// the log's edits in order. An error (naming `path`) when the log is of another survey or a
// run falls outside it.
Expected<std::vector<std::uint8_t>> ApplyEditLog(const EditLog& log,
                                                 const survey::PingSeries& pings,
                                                 const std::string& path);

// P/edits.json applied to `pings`: an empty vector when there is no such file, the edits
// otherwise; an error names the file and what is wrong with it.
Expected<std::vector<std::uint8_t>> LoadEdits(const std::string& out_dir,
                                              const survey::PingSeries& pings);

}  // namespace pitmap::proc::survey
