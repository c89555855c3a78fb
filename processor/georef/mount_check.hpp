// SPDX-License-Identifier: MIT
// Does the configured sonar mount explain the soundings? A check against the data, before any
// calibration: with the right mount the vehicle's roll and pitch are taken out of every ping,
// so the across-fan slope of the floor under a ping does not follow the waves. With the wrong
// one it does, in a way that names the mistake:
//   - the head turned by 180 deg from what vehicle.yaml says (connector forward for aft, or
//     port for starboard): the fan is mirrored and a flat floor tilts by twice the roll
//     (gain about 2 on the roll);
//   - turned by 90 deg (port or starboard for aft or forward): the fan is put along the track,
//     it keeps the roll it was measured with and gains the pitch (about 1 on each).
// Per ping, a line is fitted to the soundings within a window fixed on the ground (height
// against the horizontal distance u along the fan from the point under the sensor, |u| <= the
// nadir depth x tan(max_angle_deg); a window of beam angles would slide with the roll and turn
// the floor's curvature into a slope); pings whose floor is not a plane (walls, rubble) are left
// out. The slope's wave-rate part (the slope minus its moving
// mean over window_s) is regressed on the vehicle roll's and pitch's (the same moving-mean
// high-pass, a linear filter, so the gains are unchanged by it) with Huber weights. Terrain that
// changes within the window is the regression's noise; the gains' standard errors say how well
// the survey's own motion resolves them. A survey whose vehicle hardly rolled cannot be checked
// and says so.
// Thread safety: reentrant.
#pragma once

#include <cstdint>
#include <string>

#include "processor/georef/georef.hpp"

namespace pitmap::proc::georef {

struct MountCheckConfig {
    double max_angle_deg = 25;       // floor line over |u| <= nadir depth x tan(this)
    std::int64_t min_beams = 20;     // per ping
    double min_spread_m = 2.0;       // horizontal spread of those soundings along the fan
    double max_fit_rms_m = 0.3;      // floor line residual; above: not a plane (left out)
    double window_s = 4.0;           // moving-mean high-pass of slope, roll and pitch
    std::int64_t min_pings = 200;    // with a floor line
    double min_motion_sd_deg = 0.2;  // roll (or pitch) sd after the high-pass: enough motion
    double max_gain = 0.5;           // a gain beyond this, and ...
    double min_significance = 4.0;   // ... both gains this many sigmas from 0: the mount is wrong
};

struct MountCheck {
    bool checked = false;                  // the data could resolve the gains
    bool consistent = true;                // the mount explains the soundings (or not checked)
    double roll_gain = 0, pitch_gain = 0;  // d(slope) / d(roll), d(slope) / d(pitch)
    double roll_gain_sd = 0, pitch_gain_sd = 0;
    double significance = 0;                   // sqrt(g' C^-1 g) of the two gains
    double roll_sd_deg = 0, pitch_sd_deg = 0;  // the motion, after the high-pass
    std::int64_t pings = 0;                    // with a floor line
    std::string likely_cause;                  // when not consistent: which key, which mistake
    std::string message;                       // one line for the terminal and the summary
};

MountCheck CheckMountAgainstAttitude(const GeorefResult& geo, const MountCheckConfig& config = {});

// Least-squares line z = a + b u over one ping's soundings, from running sums.
struct MountLineSums {
    std::int64_t n = 0;
    double u = 0, z = 0, uu = 0, uz = 0, zz = 0;
    void Add(double x, double y) {
        ++n;
        u += x;
        z += y;
        uu += x * x;
        uz += x * y;
        zz += y * y;
    }
};

// CheckMountAgainstAttitude over a view read a block at a time (decision 033): Add each block
// in turn (whole pings: a ping's soundings all in one block; its ping indices into geo.pings,
// the result so far), then Check on the result. The same sums in the same order: the same
// check.
class MountCheckByBlocks {
public:
    explicit MountCheckByBlocks(const MountCheckConfig& config = {}) : cfg_(config) {}
    void Add(const GeorefResult& geo, const GeorefPoints& block);
    MountCheck Check(const GeorefResult& geo) const;

private:
    MountCheckConfig cfg_;
    std::vector<MountLineSums> sums_;  // per ping of the result
};

}  // namespace pitmap::proc::georef
