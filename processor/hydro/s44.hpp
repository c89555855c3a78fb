// SPDX-License-Identifier: MIT
// IHO S-44 Edition 6.1.0 (2022, "IHO Standards for Hydrographic Surveys") quality control of a
// survey: per sounding and per grid node, does the uncertainty meet the chosen order; where
// does the coverage leave holidays; how do crossing lines agree.
//
// S-44 Ed. 6.1.0 Table 1 (minimum standards, 95 % confidence), as used here:
//   order      THU (m)           TVU a (m)  TVU b   feature detection     feature search / coverage
//   exclusive  0.5               0.15       0.0075  cubic > 0.5 m         200 % / 200 %
//   special    2                 0.25       0.0075  cubic > 1 m           100 % / 100 %
//   1a         5 + 5 % of depth  0.5        0.013   cubic > 2 m to 40 m   100 % / <= 100 %
//                                                   depth, 10 % of depth beyond
//   1b         5 + 5 % of depth  0.5        0.013   not applicable        not specified / 5 %
//   2          20 + 10 % of depth 1.0       0.023   not applicable        not specified / 5 %
// TVU limit at depth d: sqrt(a^2 + (b d)^2); THU limit: c + k d.
//
// Holidays: the survey's coverage on the grid (a node is covered when the CUBE surface has a
// value there). Empty nodes connected to the grid's border are outside the survey; the other
// empty nodes form gaps (8-connected). A gap is a holiday when the order asks for full coverage
// (exclusive, special, 1a: a feature search of 100 % or more) and the largest square of empty
// nodes inside it is at least the order's feature size (the cube that must be detected; 1a at
// the survey's median depth) and at least min_holiday_nodes nodes on a side (NOAA's 3 x 3 node
// rule). For 1b and 2 gaps are mapped but none is a holiday (5 % coverage).
//
// Crossline check (any track shape: lines, circles, spirals): a sounding is compared with the
// surface of the earlier soundings in its cell (crossline_cell_m) that were made at least
// min_time_separation_s before it with a heading at least crossing_angle_deg away from its
// ping's (as lines, modulo 180 deg): where the track crosses its own earlier lines. Their mean
// height, carried to the sounding along the DEM's gradient (slopes), needs at least
// min_reference_soundings soundings. The earlier soundings are pooled per cell, 20 s time
// block and 15 deg heading bin. Differences are summarised by |beam angle| (10 deg bins):
// count, mean, standard deviation, RMS, and the share within the order's TVU limit.
// Pure code; RunS44 is reentrant.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace pitmap::proc::hydro {

enum class S44Order { kExclusive = 0, kSpecial, kOrder1a, kOrder1b, kOrder2 };
inline constexpr int kNumS44Orders = 5;
const char* ToString(S44Order o);  // "exclusive", "special", "1a", "1b", "2"
// The order named as ToString names it; false (o untouched) for any other text.
bool S44OrderFromString(const std::string& name, S44Order* o);

struct S44Limits {
    double thu_constant_m = 0;
    double thu_depth_fraction = 0;
    double tvu_a_m = 0;
    double tvu_b = 0;
    double feature_size_m = 0;                 // cube to detect; 0 = not applicable
    double feature_depth_fraction = 0;         // beyond feature_depth_limit_m (1a: 10 %)
    double feature_depth_limit_m = 0;          // 1a: 40 m
    double coverage_percent = 0;               // bathymetric coverage required
    bool full_coverage = false;                // feature search >= 100 %: holidays apply
    double Tvu(double depth_m) const;          // 95 %, m
    double Thu(double depth_m) const;          // 95 %, m
    double FeatureSize(double depth_m) const;  // 0 = not applicable
};
const S44Limits& LimitsOf(S44Order o);

struct S44Config {
    S44Order order = S44Order::kOrder1a;
    int min_holiday_nodes = 3;          // a holiday is at least this many nodes on a side
    double crossing_angle_deg = 45;     // headings this far apart (modulo 180 deg) cross
    double min_time_separation_s = 30;  // the earlier soundings are at least this older
    double crossline_cell_m = 0;        // 0 = 2 x the grid resolution
    int min_reference_soundings = 3;    // crossing soundings needed in a cell
    std::vector<std::string> Validate() const;
};

// The soundings (grid coordinates: UTM metres, heights up in the product's datum) and pings.
struct S44Soundings {
    std::vector<double> x, y, z;
    std::vector<float> depth_m;  // below the water surface (or transducer), m
    std::vector<float> thu_95_m, tvu_95_m;
    std::vector<float> angle_deg;      // beam angle, sonar frame
    std::vector<std::uint32_t> ping;   // index into ping_t_s / ping_yaw_rad (time-sorted)
    std::vector<double> ping_t_s;      // GPS seconds
    std::vector<double> ping_yaw_rad;  // heading of the vehicle
};

// The CUBE grid as S-44 needs it (CubeGrid geometry; row j = 0 the southernmost).
// A node's THU (CUBE carries none): the mean THU of the soundings CUBE offered it, those within
// their capture distance of the node, r_c = clamp(capture_depth_fraction * depth,
// capture_min_res * resolution, capture_max_res * resolution) (CubeConfig's rule and defaults;
// the grid stage copies its CubeConfig's). Every node CUBE filled has such soundings; one that
// has none (a grid from elsewhere) is counted in S44Result::nodes_without_thu and left out of
// the nodes' THU share rather than counted as failing it.
struct S44Grid {
    double x0 = 0, y0 = 0, resolution_m = 0;
    int nx = 0, ny = 0;
    std::vector<float> elevation_m;        // NaN = empty
    std::vector<float> uncertainty_m;      // 95 %
    std::vector<float> depth_m;            // node depth for the limits (NaN where empty)
    double capture_depth_fraction = 0.05;  // CubeConfig::capture_distance_scale
    double capture_min_res = 0.71;         // CubeConfig::min_capture_distance_res
    double capture_max_res = 1.5;          // CubeConfig::max_capture_distance_res
};

struct S44Holiday {
    double x = 0, y = 0;  // centre of the gap's largest empty square, m
    double x_min = 0, y_min = 0, x_max = 0, y_max = 0;  // the gap's bounding box, m
    std::int64_t nodes = 0;                             // empty nodes in the gap
    double area_m2 = 0;
    double largest_square_m = 0;  // side of the largest empty square, m
};

struct S44AngleBin {
    double angle_lo_deg = 0, angle_hi_deg = 0;
    std::int64_t count = 0;
    double mean_m = 0, sd_m = 0, rms_m = 0;
    double within_tvu = 0;  // share of |difference| <= the order's TVU limit
};

struct S44Result {
    S44Order order = S44Order::kOrder1a;
    // Soundings and nodes within the limits of every order (index: S44Order).
    std::array<double, kNumS44Orders> soundings_within_tvu{};
    std::array<double, kNumS44Orders> soundings_within_thu{};
    std::array<double, kNumS44Orders> soundings_within_both{};
    std::array<double, kNumS44Orders> nodes_within_tvu{};
    std::array<double, kNumS44Orders> nodes_within_thu{};  // of the nodes with a THU
    std::int64_t soundings = 0, nodes = 0;
    std::int64_t nodes_without_thu = 0;  // filled nodes no sounding reaches (S44Grid)
    // Coverage and holidays (the chosen order).
    std::int64_t nodes_survey_area = 0;  // covered + inside gaps
    std::int64_t nodes_in_gaps = 0;
    double coverage_share = 0;         // covered / survey area
    double feature_size_m = 0;         // used for holidays (0: not applicable)
    std::vector<S44Holiday> holidays;  // largest first
    std::int64_t gaps = 0;             // gaps of any size
    // Per node: NaN outside the survey area, 0 covered, 1 in a gap, 2 in a holiday.
    std::vector<float> holiday_map;
    // Crossline check.
    std::int64_t crossline_compared = 0;
    double crossline_mean_m = 0, crossline_sd_m = 0, crossline_rms_m = 0;
    double crossline_within_tvu = 0;
    std::vector<S44AngleBin> crossline_by_angle;
    std::string message;
};

// Order the survey meets: the strictest order whose TVU and THU 95 % of the soundings meet;
// -1 if none.
int StrictestOrderMet(const S44Result& r, double share = 0.95);

S44Result RunS44(const S44Soundings& s, const S44Grid& g, const S44Config& config);

// RunS44 over the soundings given a block at a time (S44Soundings of a block: ping_t_s and
// ping_yaw_rad unused, the pings' own given here), twice in the same order (decision 035): the
// first pass (AddFirst) the compliance, the nodes' THU and the crossline check's reference
// cells, the second (AddSecond, after every AddFirst) the crossline comparisons. Finish gives
// RunS44's result for the soundings, bit for bit (the same sums in the same order). It holds
// the grid's sums and the reference cells, and the soundings' finite depths (4 bytes a
// sounding, for the holidays' median depth), not the soundings. `g` must outlive it.
class S44ByBlocks {
public:
    S44ByBlocks(const S44Grid& g,
                const S44Config& c,
                std::vector<double> ping_t_s,
                std::vector<double> ping_yaw_rad);
    ~S44ByBlocks();
    S44ByBlocks(const S44ByBlocks&) = delete;
    S44ByBlocks& operator=(const S44ByBlocks&) = delete;
    void AddFirst(const S44Soundings& block);
    void AddSecond(const S44Soundings& block);
    S44Result Finish();

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace pitmap::proc::hydro
