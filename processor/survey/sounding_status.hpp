// SPDX-License-Identifier: MIT
// The status of a sounding (issue 35): accepted, or rejected with the reason. Soundings are
// never deleted: the raw range stays in the survey model (PingSeries::range_counts) and the
// status says whether a stage uses it.
//
// Who decides what:
//   georef       no detection, range gate, spike (per ping, every time it georeferences) and
//                rays that could not be traced (refraction)
//   clean        free-space conflict, multipath (behind an observed surface), cluster off the
//                surface (processor/clean, on the soundings in 3D), along-track (a beam's range
//                against the same beam over the neighbouring pings)
//   grid         surface filter (against the CUBE surface's chosen hypothesis)
//   the editor   manual (pitmap edit's edit log, processor/survey/edit_log.hpp); a manual
//                restore also overrides the range gate, the spike filter and the automatic
//                cleaning (never a missing detection or a ray that cannot be traced)
// Codes are stored (survey.pitmap, the PLY's status property, edits.json): append, never
// renumber.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

namespace pitmap::proc::survey {

enum class SoundingStatus : std::uint8_t {
    kAccepted = 0,
    kNoDetection = 1,    // the sonar returned no range
    kRangeGate = 2,      // outside the configured range gate
    kSpike = 3,          // the per-ping median filter
    kRefraction = 4,     // the ray turned, surfaced or could not be steered
    kSurfaceFilter = 5,  // does not support the CUBE node's chosen hypothesis
    kFreeSpace = 6,      // lies in water other pings observed as free (fish, bubbles)
    kMultipath = 7,      // lies behind a well-observed surface along its own beam
    kCluster = 8,        // in a persistent cluster off the surface
    kManual = 9,         // rejected by hand (pitmap edit)
    kProfile = 10,       // off its beam's range over the neighbouring pings (a run of echoes)
};
inline constexpr int kNumSoundingStatus = 11;

// The stored name ("accepted", "no_detection", ..., "manual").
std::string_view ToString(SoundingStatus s);
// Whether a stored code is a known status.
inline bool IsSoundingStatus(std::uint8_t code) {
    return code < kNumSoundingStatus;
}
// Rejections that the cleaning decides (stored per sounding in the survey model).
inline bool IsCleaningStatus(SoundingStatus s) {
    return s == SoundingStatus::kSurfaceFilter || s == SoundingStatus::kFreeSpace ||
           s == SoundingStatus::kMultipath || s == SoundingStatus::kCluster ||
           s == SoundingStatus::kProfile;
}

// A hand edit of one sounding, applied on top of the automatic status.
enum class ManualEdit : std::uint8_t { kNone = 0, kReject = 1, kRestore = 2 };

// Which soundings a georeference returns, by status.
enum class SoundingView : std::uint8_t {
    kAccepted,    // what the stages use (the default)
    kRejected,    // the rejected soundings that have a position (everything but no detection and
                  // failed rays), with GeorefPoints::status: for the exports and the editor
    kCandidates,  // accepted by georef's own filters (and by a manual restore), whatever the
                  // cleaning said, without the manual rejections: what the cleaning decides on
};

// Statuses decided outside georef, per sounding of the PingSeries (index = beam_offset + beam);
// either vector may be empty (nothing decided).
struct SoundingFlags {
    std::vector<std::uint8_t> cleaning;  // SoundingStatus, kAccepted or a cleaning status
    std::vector<std::uint8_t> manual;    // ManualEdit

    SoundingStatus Cleaning(std::size_t j) const {
        return j < cleaning.size() ? static_cast<SoundingStatus>(cleaning[j])
                                   : SoundingStatus::kAccepted;
    }
    ManualEdit Manual(std::size_t j) const {
        return j < manual.size() ? static_cast<ManualEdit>(manual[j]) : ManualEdit::kNone;
    }
};

// The status of a sounding from georef's own verdict `georef` (kAccepted, kRangeGate, kSpike;
// kNoDetection and kRefraction are final) and the flags.
inline SoundingStatus Resolve(SoundingStatus georef, const SoundingFlags& f, std::size_t j) {
    if (georef == SoundingStatus::kNoDetection || georef == SoundingStatus::kRefraction)
        return georef;
    const ManualEdit m = f.Manual(j);
    if (m == ManualEdit::kRestore) return SoundingStatus::kAccepted;
    if (georef != SoundingStatus::kAccepted) return georef;
    if (m == ManualEdit::kReject) return SoundingStatus::kManual;
    return f.Cleaning(j);
}

// Counts per status (index = code).
using StatusCounts = std::array<std::int64_t, kNumSoundingStatus>;

}  // namespace pitmap::proc::survey
