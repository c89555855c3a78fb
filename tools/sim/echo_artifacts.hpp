// SPDX-License-Identifier: MIT
// Correlated echo artifacts of a multibeam in a flooded pit (issue 35): what a real Delta T
// returns besides the bottom, held over many pings or many beams so that a per-ping median
// filter does not see it. EchoArtifactConfig (scenario.hpp) holds the parameters. Kinds:
//
//   mid-water     fish schools and vegetation: spheres in the water column (centre at least
//                 school_min_depth_m down and 1 m above the bottom), alive school_lifetime_s,
//                 drifting slowly; in a ping, a school answers with probability school_fill
//                 (it is patchy), and then every beam whose axis enters it before the bottom
//                 returns the entry range.
//   bubble        bubble sweep-down and aeration: episodes of bubble_min..max_pings pings,
//                 started at random (bubble_episodes_per_min) and bubble_manoeuvre_factor times
//                 as often while the vehicle turns or pitches hard; a sector of the fan is cut
//                 into clouds of 4-16 beams, each returning a near-field echo at one range
//                 (bubble_min..max_range_m), nothing, or left alone.
//   dropout       the beams of a bubble episode that return nothing (no sounding: counted, but
//                 not an artifact sounding).
//   multipath     multipath and side-lobe ghosts at grazing incidence and under steep walls: an
//                 episode holds a few neighbouring beams for tens of pings, returning the true
//                 range times (1 + excess): a point behind the surface.
//   smile         the nadir side-lobe "smile": at short nadir range, the beams near nadir whose
//                 true range is longer than the nadir range return the nadir range (a curve up
//                 from the true surface across the centre of the swath).
//   outlier       not this model's: SonarConfig's uncorrelated coarse outliers, listed in the
//                 truth too so that a cleaning can be scored on every false sounding.
//
// An artifact replaces the beam's range (and intensity); an artifact range that would lie
// within max(0.3 m, 5 range sigmas) of the true one is not made (the beam keeps its echo), so
// every beam listed is a false sounding.
//
// Thread safety: none; Apply is called once per ping in ping order (the persistent artifacts
// carry state from ping to ping), which makes the result depend only on the seed.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "common/se3.hpp"
#include "tools/sim/backscatter.hpp"
#include "tools/sim/scenario.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {

struct SimPing;

enum class EchoArtifactKind : std::uint8_t {
    kNone = 0,
    kMidWater = 1,
    kBubble = 2,
    kDropout = 3,
    kMultipath = 4,
    kSmile = 5,
    kOutlier = 6,
};
inline constexpr int kNumEchoArtifactKinds = 7;
// "mid_water", "bubble", "dropout", "multipath", "smile", "outlier" ("none" for kNone).
const char* EchoArtifactName(EchoArtifactKind kind);

// The vehicle's motion at a ping, for the bubble episodes.
struct PingMotion {
    double yaw_rate_deg_s = 0;
    double pitch_rate_deg_s = 0;
};

// Slope classes [edge i, edge i + 1), degrees of the true surface under a beam's true hit, in
// which the good soundings are counted (the scorer's classes, tools/eval/scores.hpp).
inline constexpr double kArtifactSlopeEdgesDeg[] = {0, 20, 45, 91};
inline constexpr int kNumArtifactSlopeClasses = 3;

// A run of consecutive beams of one ping with the same artifact kind.
struct ArtifactRun {
    std::uint32_t ping_number = 0;
    std::uint16_t first_beam = 0;
    std::uint16_t num_beams = 0;
    EchoArtifactKind kind = EchoArtifactKind::kNone;
};

// The truth per beam (truth_io.hpp artifacts.bin / artifacts.json): every beam of every ping
// that is not its own echo, as runs sorted by (ping_number, first_beam).
struct ArtifactTruth {
    EchoArtifactConfig config;
    int beams_per_ping = 0;
    std::int64_t pings = 0;
    double first_ping_gps_s = 0;  // GPS seconds of ping 0's transmit; ping k at + k / rate
    double ping_rate_hz = 0;
    std::vector<ArtifactRun> runs;
    std::int64_t beams_by_kind[kNumEchoArtifactKinds] = {};  // [kind]: beams listed
    std::int64_t good_soundings = 0;  // beams with a detection that are not listed
    std::int64_t good_by_slope[kNumArtifactSlopeClasses] = {};
    // The returned artifact beams (mid-water, bubble, multipath, smile): false soundings.
    std::int64_t artifact_soundings() const;
    // Adds one ping (ping.artifact set by EchoArtifactModel::Apply); pings in order.
    void Add(const SimPing& ping, const PitWorld& world);
    // The kind of (ping, beam): kNone if not listed (binary search over the runs).
    EchoArtifactKind KindOf(std::int64_t ping_number, int beam) const;
};

class EchoArtifactModel {
public:
    EchoArtifactModel(const EchoArtifactConfig& config,
                      const SonarConfig& sonar,
                      const BackscatterConfig& backscatter,
                      const PitWorld& world,
                      std::uint64_t seed);
    // Replaces the ranges (83P counts) and intensities of the artifact beams of `ping` and
    // sets ping.artifact; also lists the model's coarse outliers (kOutlier). Pings must come
    // in increasing ping_number order. `t_s`: seconds since the survey start.
    void Apply(SimPing& ping, const Pose& T_world_sonar, double t_s, const PingMotion& motion);

private:
    struct School {
        Eigen::Vector3d centre;
        double radius_m;
    };
    struct Episode {
        std::int64_t last_ping = -1;  // inclusive
        int first_beam = 0, num_beams = 0;
        double a = 0, b = 0;  // kind-specific (multipath: excess)
    };
    School SchoolAt(int index, double t_s) const;
    double Intensity(double range_m, double target_db, std::mt19937_64& rng) const;

    EchoArtifactConfig cfg_;
    SonarConfig sonar_;
    BackscatterConfig bs_;
    const PitWorld& world_;
    std::uint64_t seed_;
    std::mt19937_64 rng_;
    Episode bubble_;
    Episode smile_;
    std::vector<Episode> multipath_;
};

}  // namespace pitmap::sim
