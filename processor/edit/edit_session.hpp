// SPDX-License-Identifier: MIT
// EditSession: the state behind `pitmap edit P` (issue 35): every sounding of P/survey.pitmap
// that has a position, on the newest trajectory, with its automatic status, the edit log
// (P/edits.json) applied on top, and the edits the page makes (reject, restore, undo), each
// saved at once.
//
// Design (5.9 M soundings must stay under 1.5 GB and a lasso of 100 k answer in < 1 s):
//   - At open, the survey is georeferenced twice with no hand edits (georef::Georeference, the
//     accepted and the rejected views: together every sounding that has a position, with what
//     georef and the cleaning decided), then the edit log is applied on top. Per sounding the
//     session keeps 21 bytes: float32 east/north/up from the session's centre, its flat index
//     in the ping series (beam_offset + beam), its automatic status and its TVU (95 %, float32;
//     NaN when the TPU could not be computed). The georeferenced views, the navigation and the
//     rest of the model are dropped after open; the ping series stays (the edit log's runs).
//   - Selections run here over every sounding (selection.hpp: TBB, the page's polygon and
//     matrix), never on what the page shows.
//   - The page shows a display set: every k-th sounding (k = ceil(n / max_display_points)), in
//     the session's order; positions, TVU and status are sent as binary arrays of it.
//   - A status is resolved from the automatic one and the manual edit as
//     survey::Resolve does (EffectiveStatus).
// An edit (Apply) touches only the soundings whose status it changes: a reject takes the
// accepted soundings in the polygon, a restore the rejected ones. It becomes one entry of the
// edit log (its runs: survey::RunsOf) and the log is written (survey::WriteEditLog) before the
// answer; undo removes the last entry of the log (whoever made it) and writes it again.
// Failure model: a survey that cannot be loaded, casts that cannot be read, an edit log that is
// damaged or of another survey: Open fails naming the file (nothing is applied). An edit log
// that cannot be written: the edit is not made (the in-memory state is rolled back) and the
// error names the file. Someone else writing P/edits.json while the session runs is not seen
// (the session's next write replaces it).
// Thread safety: every public member takes the session's lock.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/edit/selection.hpp"
#include "processor/georef/georef.hpp"
#include "processor/survey/edit_log.hpp"
#include "processor/survey/series.hpp"
#include "processor/survey/sounding_status.hpp"
#include "processor/survey/survey.hpp"

namespace pitmap::proc::edit {

struct EditSessionConfig {
    georef::GeorefConfig georef;               // as the stages georeference (pitmap --config)
    std::size_t max_display_points = 1500000;  // the page's display set, at most
    double tpu_sound_speed_mps = 1500;         // the grid stage's TPU settings
    double ins_sigma_max_age_s = 5.0;
    bool compute_tvu = true;             // false: TVU is NaN everywhere (faster open)
    int num_threads = 0;                 // 0 = all cores (TBB)
    std::string source = "pitmap edit";  // an edit's "source" in the log
    std::vector<std::string> Validate() const;
};

// The status of a sounding whose automatic status (georef's and the cleaning's, no hand edit)
// is `automatic`, with the hand edit `manual`: survey::Resolve's rule.
survey::SoundingStatus EffectiveStatus(survey::SoundingStatus automatic, survey::ManualEdit manual);

enum class EditAction { kReject, kRestore };

struct EditOutcome {
    std::size_t selected = 0;  // soundings inside the polygon (every status)
    std::size_t changed = 0;   // whose status the edit changed (0: no edit was logged)
    std::size_t edits = 0;     // entries in the log now
    double seconds = 0;        // selection and bookkeeping, without the file write
};

class EditSession {
public:
    // Loads P/survey.pitmap and P/edits.json (see the failure model).
    static Expected<std::unique_ptr<EditSession>> Open(const std::string& out_dir,
                                                       const EditSessionConfig& config);
    // From a model already in memory (tests, the benchmark); the edit log is still
    // out_dir/edits.json.
    static Expected<std::unique_ptr<EditSession>> FromModel(survey::SurveyModel model,
                                                            const std::string& out_dir,
                                                            const EditSessionConfig& config);

    // A reject or restore of the soundings inside `query`, logged and saved.
    Expected<EditOutcome> Apply(EditAction action, const SelectionQuery& query);
    // The soundings inside `query` (indices into the session's soundings), without editing.
    std::vector<std::uint32_t> Select(const SelectionQuery& query) const;
    // Removes the last edit of the log and saves it; an error when there is none.
    Expected<EditOutcome> Undo();

    // The session's soundings (positions in metres from centre(), ENU).
    std::size_t size() const { return flat_.size(); }
    std::size_t num_soundings() const { return pings_.num_soundings(); }
    std::size_t display_stride() const { return stride_; }
    std::size_t display_size() const { return (size() + stride_ - 1) / stride_; }
    const std::array<double, 3>& centre() const { return centre_; }
    bool has_tvu() const { return has_tvu_; }
    // The display set's arrays (little-endian float32 x y z; float32 TVU; uint8 status).
    std::string DisplayPositions() const;
    std::string DisplayTvu() const;
    std::string DisplayStatus() const;
    // Of every sounding of the session: the effective status, flat indices of the manual
    // rejections, counts per status.
    std::vector<std::uint8_t> Statuses() const;
    const std::vector<std::uint32_t>& flat_index() const { return flat_; }
    const std::vector<float>& positions() const { return xyz_; }
    survey::StatusCounts Counts() const;
    std::size_t num_edits() const;
    std::string edit_log_path() const { return out_dir_ + "/" + survey::kEditLogFileName; }
    // What the open found (trajectory version, counts, TVU source), for the page and the log.
    const std::string& description() const { return description_; }

private:
    EditSession() = default;
    survey::SoundingStatus StatusOf(std::size_t i) const {
        return EffectiveStatus(static_cast<survey::SoundingStatus>(auto_status_[i]),
                               static_cast<survey::ManualEdit>(manual_[flat_[i]]));
    }
    Status SaveLocked();

    mutable std::mutex mutex_;
    EditSessionConfig config_;
    std::string out_dir_;
    survey::PingSeries pings_;
    survey::EditLog log_;
    std::vector<std::uint8_t> manual_;  // per sounding of the ping series (ManualEdit)
    std::array<double, 3> centre_{};
    std::vector<float> xyz_;
    std::vector<std::uint32_t> flat_;
    std::vector<std::uint8_t> auto_status_;
    std::vector<float> tvu_;
    bool has_tvu_ = false;
    std::size_t stride_ = 1;
    std::string description_;
};

}  // namespace pitmap::proc::edit
