// SPDX-License-Identifier: MIT
// Sound-velocity files from disk: CARIS .svp, CSV, two-column text (processor/svp/cast.hpp) and the
// probes' own files, AML, CastAway, HYPACK .vel, Kongsberg .asvp, MVP .s12, Sea-Bird .cnv,
// Simrad .ssp, Valeport MIDAS (processor/svp/probe_casts.hpp), each recognised by content.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/survey/survey.hpp"
#include "processor/svp/cast.hpp"
#include "processor/svp/refraction.hpp"

namespace pitmap::proc::io {

// Reads every file in order; the casts of all files, in file order. An unreadable, empty,
// over-large (> 64 MiB) or malformed file is an error naming it (and the line); a file in none of
// the formats is an error listing them.
Expected<std::vector<svp::SoundSpeedCast>> ReadSoundSpeedFiles(
    const std::vector<std::string>& paths);

// The casts of the survey model's refraction record, read from its files; null for straight
// rays. A missing or bad cast file is an error naming it; casts that the refraction cannot use
// (svp::Refraction::Check) are an error listing every problem.
Expected<std::shared_ptr<const svp::Refraction>> BuildRefraction(const survey::RefractionRecord& r);

}  // namespace pitmap::proc::io
