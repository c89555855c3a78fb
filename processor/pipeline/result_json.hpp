// SPDX-License-Identifier: MIT
// Internal to processor/pipeline: summary.json entries of the stages' Results, through
// nlohmann's type macros where a Result's field names are the JSON keys (each macro lists the
// fields written; a field not listed is not part of summary.json). Keys the report and tests
// read; renaming a field renames its key, so do that only together with them.
#pragma once

#include <nlohmann/json.hpp>

#include "processor/calib/boresight.hpp"
#include "processor/fusion/tsdf.hpp"
#include "processor/georef/georef.hpp"
#include "processor/io/ingest.hpp"
#include "processor/slam/slam.hpp"

namespace pitmap::proc::io {
// events_by_channel is printed by `pitmap info`, not stored.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(IngestCounts,
                                   files,
                                   bytes,
                                   events,
                                   corrupt_events,
                                   resync_bytes,
                                   truncated_events,
                                   length_repairs,
                                   files_skipped,
                                   decode_failures,
                                   nav_samples,
                                   nav_without_time,
                                   nav_not_good,
                                   nav_not_navigating,
                                   nav_degraded,
                                   nav_conflicts,
                                   ping_conflicts,
                                   nav_gaps,
                                   ping_gaps,
                                   sessions,
                                   nav_duplicates,
                                   stddev_samples,
                                   pings,
                                   pings_without_time,
                                   pings_bad,
                                   ping_duplicates,
                                   raw_chunks_decoded,
                                   raw_skipped_bytes,
                                   raw_decode_errors)
}  // namespace pitmap::proc::io

namespace pitmap::proc::georef {
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(GeorefCounts,
                                   pings_in,
                                   pings_georeferenced,
                                   pings_outside_nav,
                                   pings_in_nav_gap,
                                   pings_bad_header,
                                   soundings_in,
                                   no_detection,
                                   range_gate,
                                   spikes,
                                   refraction_failed,
                                   cleaned,
                                   manual,
                                   points)
}  // namespace pitmap::proc::georef

namespace pitmap::proc::calib {
// low_drift is not stored.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(
    SegmentScore, start_s, end_s, overlap_cells, max_position_stddev_m, max_heading_stddev_deg)
}  // namespace pitmap::proc::calib

namespace pitmap::proc::slam {
NLOHMANN_JSON_SERIALIZE_ENUM(SlamStage,
                             {{SlamStage::kRigid, "rigid"}, {SlamStage::kSemiRigid, "semi_rigid"}})
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(SlamIteration,
                                   stage,
                                   iteration,
                                   num_pairs,
                                   num_section_pairs,
                                   max_section_partners,
                                   normal_equation_blocks,
                                   factor_nonzeros,
                                   factor_flops,
                                   windows,
                                   cost,
                                   cost_after,
                                   rejected_steps,
                                   damping,
                                   pair_score_m,
                                   pair_rms_m,
                                   consistency_m,
                                   max_step_rotation_rad,
                                   max_step_translation_m,
                                   best)
}  // namespace pitmap::proc::slam

namespace pitmap::proc::fusion {
// The integration counts; elapsed_s is stored as integrate_seconds beside them.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(IntegrateResult,
                                   scans,
                                   beams_used,
                                   beams_no_detection,
                                   beams_out_of_range,
                                   scans_out_of_bounds,
                                   beams_inconsistent,
                                   voxel_updates,
                                   prepare_s,
                                   rasterise_s,
                                   merge_s,
                                   cpu_s)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(WeightHistogram, edges, counts)
}  // namespace pitmap::proc::fusion
