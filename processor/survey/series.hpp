// SPDX-License-Identifier: MIT
// Plain time series the processor works on: INS navigation and multibeam pings in GPS time.
// Produced by processor/io (LCM logs, vendor files), consumed by the stages. No I/O here.
//
// Times are utime_gps (GPS microseconds since 1980-01-06, docs/conventions.md). Attitudes are
// radians, roll/pitch/yaw of the vehicle (FRD) frame relative to NED (common/frames.hpp).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "common/geodesy.hpp"

namespace pitmap::proc::survey {

inline constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// One INS solution (INSPVA/INSPVAS/INSPVAX) at the INS reference point.
struct NavSample {
    std::int64_t utime_gps = 0;
    Geodetic position;                                // ellipsoidal height
    double roll_rad = 0, pitch_rad = 0, yaw_rad = 0;  // R_ned_vehicle angles
    Eigen::Vector3d velocity_enu_mps = Eigen::Vector3d::Zero();
    std::int32_t ins_status = -1;     // NovAtel INS status enum
    std::int32_t position_type = -1;  // NovAtel position type, -1 if none
};

// INS standard deviations (INSSTDEV, or the ones INSPVAX carries), 1 sigma.
struct NavStdDev {
    std::int64_t utime_gps = 0;
    float north_m = kNaNf, east_m = kNaNf, up_m = kNaNf;
    float roll_deg = kNaNf, pitch_deg = kNaNf, yaw_deg = kNaNf;
};

// Time-sorted, one sample per time (duplicates removed by the reader).
struct NavSeries {
    std::vector<NavSample> samples;
    std::vector<NavStdDev> stddevs;
    // GPS - UTC seconds from the receiver's TIME log; -1 when none was seen.
    int leap_seconds = -1;
};

// The 83P header fields the processing needs (all of one ping, without the beams).
struct PingHeader {
    std::int64_t utime_gps = 0;  // transmit time
    std::int64_t ping_number = 0;
    double sound_speed_mps = 1500.0;  // header value (1500 when not set)
    bool sound_speed_valid = false;
    double range_resolution_m = 0;  // metres per range count
    double start_angle_deg = 0;     // beam 0, from nadir, positive to starboard
    double angle_increment_deg = 0;
    double profile_tilt_deg = 0;    // fore/aft fan tilt
    std::uint32_t beam_offset = 0;  // first beam in PingSeries::range_counts
    std::uint16_t num_beams = 0;
    // aid_roll_deg and aid_pitch_deg (below) are the head's own sensor's, sampled at the
    // interrogation on the sonar's clock (the external fields are NMEA-fed, as stale as the
    // position): they time the clock's rate (calib::EstimateSonarClockRate). Sits in what was
    // padding, so the survey file's ping records keep their size.
    bool aid_attitude_at_ping = false;
    // What the topside program wrote beside its clock, NaN when absent: a position from its
    // NMEA feed (the last fix it had, so up to a fix interval stale), and the head's attitude
    // (internal sensor, else the external fields). Only used to find an unknown sonar clock
    // offset (processor/calib/sonar_clock.hpp); in the sonar head's own frame.
    double aid_latitude_deg = std::numeric_limits<double>::quiet_NaN();
    double aid_longitude_deg = std::numeric_limits<double>::quiet_NaN();
    double aid_roll_deg = std::numeric_limits<double>::quiet_NaN();
    double aid_pitch_deg = std::numeric_limits<double>::quiet_NaN();
    double aid_heading_deg = std::numeric_limits<double>::quiet_NaN();
};

// Where the pings' times come from.
enum class PingClock : std::uint32_t {
    kGpsStamped = 0,     // pitmap-acqd's GPS-disciplined receive stamps (residual latency: ms)
    kTopsideHeader = 1,  // the 83P header clock of the topside PC (offset unknown: s to hours)
};

// Time-sorted pings; the raw range counts of all pings in one flat array.
struct PingSeries {
    std::vector<PingHeader> pings;
    std::vector<std::uint32_t> range_counts;   // 0 = no detection
    PingClock clock = PingClock::kGpsStamped;  // kTopsideHeader if any ping came from a .83P file
    // The 83P per-beam intensities (normalised amplitude, raw counts, no physical unit), beside
    // range_counts: empty when no ping carried any (83P v1.00, or v1.10 without them), else one
    // per range count, 0 where a ping had none.
    std::vector<std::uint16_t> intensities;
    // Per-beam angles (degrees from the head's normal, positive to starboard) of sonars whose
    // beams are not equally spaced (R2Sonic equi-distant mode, from XTF): empty when every
    // ping's beams are at start_angle_deg + i * angle_increment_deg, else one per range count,
    // NaN for the beams of a ping that has none (its header's angles then hold).
    std::vector<float> beam_angles_deg;
    std::size_t num_soundings() const { return range_counts.size(); }
    bool has_intensities() const { return !intensities.empty(); }
    bool has_beam_angles() const { return !beam_angles_deg.empty(); }
    // Beam i of ping h: its own angle when it has one, else the header's start + i * increment.
    double BeamAngleDeg(const PingHeader& h, std::size_t i) const {
        if (!beam_angles_deg.empty()) {
            const float a = beam_angles_deg[h.beam_offset + i];
            if (std::isfinite(a)) return static_cast<double>(a);
        }
        return h.start_angle_deg + static_cast<double>(i) * h.angle_increment_deg;
    }
};

// The navigation and the pings of one survey: what ingest read (processor/io/ingest.hpp) and
// the survey model keeps (SurveyModel::ingest).
struct IngestedSeries {
    NavSeries nav;
    PingSeries pings;
};

// Sorts by time, drops repeated messages (the same time and the same content: the first kept)
// and rebuilds beam offsets. Two samples or pings of one time whose content differs (beyond
// float rounding: 5 cm, 0.05 deg; for pings any range or the ping number) are not repeats: a
// logger's clock that stepped back, or two recordings of different things at one time. Their
// time is appended to `conflicts` when given (ingest names the files and stops when they are
// many). Of two nav samples the first is kept; two pings are both kept, the later one a
// microsecond later (ping times stay strictly increasing).
void SortAndDeduplicate(NavSeries& nav, std::vector<std::int64_t>* conflicts = nullptr);
void SortAndDeduplicate(PingSeries& pings, std::vector<std::int64_t>* conflicts = nullptr);

// Adds `correction_s` (rounded to the microsecond) to every ping time: a sonar clock correction.
// Shifting by -x undoes a shift by x exactly.
void ShiftPingTimes(PingSeries& pings, double correction_s);

// A sonar clock that also runs at the wrong rate (a PC crystal is tens of ppm off): every ping
// time t (microseconds) gains correction_s + rate * (t - reference_utime), rounded to the
// microsecond. Unlike the constant shift this one is not undone exactly by its opposite (two
// neighbouring microseconds can round to one), so it is applied once, at georef.
void ShiftPingTimes(PingSeries& pings,
                    double correction_s,
                    double rate,
                    std::int64_t reference_utime);

}  // namespace pitmap::proc::survey
