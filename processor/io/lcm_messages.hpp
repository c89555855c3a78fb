// SPDX-License-Identifier: MIT
// The daemon's decoded LCM messages as the processor's types, in one place for the two readers
// of them: ingest (logs on shore, processor/io/ingest.cpp) and pitmap live (processor/live).
#pragma once

#include "processor/georef/georef.hpp"

namespace pitmap {
class ins_pva_t;
class ins_stddev_t;
class multibeam_ping_t;
}  // namespace pitmap

namespace pitmap::proc::io {

// Position, attitude (radians, yaw wrapped to (-pi, pi]), ENU velocity and status.
survey::NavSample NavSampleOf(const pitmap::ins_pva_t& m);
// The standard deviations INSPVAX (has_stddev) and INSSTDEV carry, at their GPS time.
survey::NavStdDev NavStdDevOf(const pitmap::ins_pva_t& m);
survey::NavStdDev NavStdDevOf(const pitmap::ins_stddev_t& m);
// Time, ping number, sound speed, range resolution and fan geometry; beam_offset and
// num_beams are the caller's (they depend on where the ranges go).
survey::PingHeader PingHeaderOf(const pitmap::multibeam_ping_t& m);

}  // namespace pitmap::proc::io
