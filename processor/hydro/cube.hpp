// SPDX-License-Identifier: MIT
// CUBE, the Combined Uncertainty and Bathymetry Estimator (Calder & Mayer 2003, "Automatic
// processing of high-rate, high-density multibeam echosounder data", G3 4(6); parameters as in
// Calder & Wells 2007, the CUBE user's manual): a grid of estimation nodes, each tracking one or
// more depth hypotheses.
//   1. Each sounding (x, y, z, sigma_v, sigma_h) is offered to every node within its capture
//      distance r_c = clamp(capture_distance_scale * depth, min, max) (times the resolution for
//      min/max), with its vertical variance grown with the distance d from the node:
//        sigma_n^2 = sigma_v^2 (1 + ((d + rho sigma_h) / resolution)^alpha)       [C&M eq. 9]
//      (rho = horizontal_error_scale, alpha = distance_exponent). With slope_correction the
//      sounding's height is first carried to the node along the predicted surface's gradient g
//      (z_n = z + g . (x_n - x)), and (|g| sigma_h)^2 is added: on a steep pit wall a sounding
//      a few decimetres away otherwise differs from the node by more than its uncertainty and
//      opens a false hypothesis (plain CUBE assumes a locally flat seabed). The part of it from
//      the pass-common horizontal error, (|g| sigma_h_common)^2, is pass-common too (below).
//   2. Each node holds a median pre-filter queue of queue_length soundings (C&M §3.3); once full,
//      the median leaves the queue and updates the node. At the end the queue is flushed,
//      median first.
//   3. Update (C&M §3.2, eq. 4-6): the hypothesis with the smallest normalised innovation
//      |z - mu| / sqrt(s^2 + sigma_n^2) takes the sounding by a Kalman step
//      (s'^2 = (1/s^2 + 1/sigma_n^2)^-1, mu' = mu + s'^2/sigma_n^2 (z - mu)); when that smallest
//      innovation exceeds hypothesis_gate (CUBE's "estimate offset", 4), the sounding is not
//      explained by any hypothesis and starts a new one (intervention).
//   4. Disambiguation (C&M §3.4) picks one hypothesis per node: kDensity the one with the most
//      soundings; kLocale the one closest to the median of the neighbouring nodes' (within
//      locale_radius nodes) strongest hypotheses; kPredictedSurface the one closest to the
//      predicted surface (the median height of the soundings in cells of
//      predicted_surface_cells x resolution, bilinear). Ties go to the denser hypothesis.
// Outputs per node: elevation (the chosen hypothesis' mean), uncertainty (95 %), density
// (soundings in the chosen hypothesis), hypotheses (their number). Empty nodes are NaN / 0.
// The uncertainty, when every sounding of the hypothesis states the part of its vertical
// variance that is common to the soundings of one pass (CubeSounding::sigma_common_m: the
// INS's height, attitude, mount, sound speed: what does not average over the soundings of a
// pass; plus, with slope_correction, |g|^2 sigma_h_common^2, the pass-common horizontal
// error seen through the slope) (issue 36 item 3):
//   sigma_node^2 = sum_i w_i^2 s_i^2 / (sum_i w_i)^2
//                  + mean_i(c_i^2) (1 / P^2) sum_p sum_q exp(-|t_p - t_q| / tau),
// the independent parts (range noise, pointing: s_i^2 = sigma_v,i^2 - c_i^2 + the slope term's
// independent part) averaged as the Kalman step weights them (w_i = 1 / sigma_n,i^2, the
// variance grown with the distance: C&M eq. 9 sets the weights, it is no error of the
// sounding's; before, 1 / sum_i 1 / (sigma_n,i^2 - c_i^2) took the grown variance, the common
// part's growth included, as the error and overstated floors' nodes 1.3x), the common part
// averaged over the node's P passes as far as they are independent: a Gauss-Markov error of
// correlation time tau = common_correlation_s (the INS's), the passes at times t_p (a sounding
// of the node more than pass_gap_s from every earlier pass starts one; at most kMaxPasses are
// counted, the rest joining none: conservative). Otherwise 1.96 times
// the greater of the hypothesis' posterior standard deviation and the standard deviation of its
// soundings (the convention of CARIS's CUBE surfaces, since the posterior alone shrinks as
// 1/sqrt(n) and ignores errors common to the soundings), which overstates a well-sampled node's
// error several times (docs/uncertainty.md).
// Horizontal coordinates are any metric, north-up plane (pitmap uses UTM); heights are up.
// Thread safety: RunCube is reentrant; nodes are updated in row bands, each band taking the
// soundings in input order, so results do not depend on the thread count.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace pitmap::proc::hydro {

struct CubeSounding {
    double x = 0, y = 0;  // horizontal, m
    double z = 0;         // height, m, up
    float sigma_v_m = 0;  // vertical 1 sigma (TVU / 1.96)
    float sigma_h_m = 0;  // horizontal 1 sigma, per axis (THU / 2.45)
    float depth_m = 0;    // below the transducer, m (resolution and capture distance)
    // The part of sigma_v_m common to the soundings of one pass (1 sigma, m; <= sigma_v_m);
    // NaN = unknown (the node uncertainty then takes the convention above).
    float sigma_common_m = std::numeric_limits<float>::quiet_NaN();
    float time_s = 0;  // the sounding's time from any epoch, s (tells passes apart)
    // The part of sigma_h_m common to the soundings of one pass (1 sigma per axis, m;
    // <= sigma_h_m; NaN = unknown, taken as none): on a slope |g| it moves the sounding's height
    // at the node by |g| times it for the whole pass, so |g|^2 sigma_h_common^2 joins the
    // pass-common variance instead of the independent part (issue 36 item 3).
    float sigma_h_common_m = std::numeric_limits<float>::quiet_NaN();
};

enum class Disambiguation { kDensity = 0, kLocale, kPredictedSurface };
const char* ToString(Disambiguation d);

struct CubeConfig {
    double resolution_m = 0;                   // node spacing, m; 0 = from the depth (below)
    double resolution_depth_fraction = 0.025;  // auto: median depth * this (~ a 1.5 deg beam's
                                               // footprint), rounded down to 1, 2, 2.5 or 5 x 10^k
    double min_resolution_m = 0.1;             // auto resolution bounds, m
    double max_resolution_m = 10.0;
    double capture_distance_scale = 0.05;    // capture distance, share of the depth (CUBE: 5 %)
    double min_capture_distance_res = 0.71;  // ... at least this many resolutions (the node's
                                             // cell half-diagonal) ...
    double max_capture_distance_res = 1.5;   // ... and at most this many
    double distance_exponent = 2.0;          // alpha
    double horizontal_error_scale = 1.96;    // rho
    int queue_length = 11;                   // median pre-filter; 1 = none
    // Soundings of a node further apart in time than this are of different passes.
    double pass_gap_s = 10.0;
    // Correlation time of the pass-common errors between passes (Gauss-Markov): the INS's
    // height and attitude error (a minute for an RTK INS: the simulator's tau).
    double common_correlation_s = 60.0;
    double hypothesis_gate = 4.0;     // normalised innovation that opens a hypothesis
    bool slope_correction = true;     // carry soundings along the predicted surface
    int predicted_surface_cells = 4;  // predicted-surface cell, in resolutions
    Disambiguation disambiguation = Disambiguation::kPredictedSurface;
    int locale_radius = 2;                // kLocale: neighbourhood radius, nodes
    std::int64_t max_nodes = 20'000'000;  // refuse grids larger than this (~150 B a node)
    int num_threads = 0;                  // 0 = all cores (TBB)

    std::vector<std::string> Validate() const;
};

// One hypothesis of a node.
inline constexpr int kMaxPasses = 8;
struct CubeHypothesis {
    double mean_m = 0;
    double variance_m2 = 0;    // posterior variance of the mean
    std::int32_t count = 0;    // soundings taken
    double sample_mean_m = 0;  // unweighted mean of the soundings (Welford)
    double m2 = 0;             // sum of their squared deviations (Welford)
    // The pass-common model (above): sum of 1 / independent variance, sum of the common
    // variances, soundings that stated theirs, the passes' first times.
    double independent_information = 0;
    double common_variance_sum = 0;
    std::int32_t common_count = 0;
    // The Kalman weights w = 1 / v (v: the grown variance at the node) and sum w^2 s^2 (s^2:
    // the sounding's own independent variance, without the distance growth), over the
    // soundings that stated s^2: the independent part of the weighted mean's variance is
    // sum w^2 s^2 / (sum w)^2.
    double weight_sum = 0;
    double weighted_independent = 0;
    std::int32_t measured_count = 0;
    std::int32_t passes = 0;
    std::array<float, kMaxPasses> pass_time_s{};
    double SampleSd() const;
    // 1 sigma of the node from the pass-common model (tau: common_correlation_s), or NaN where
    // a sounding did not state its common part.
    double PassModelSd(double tau_s) const;
    // 1 sigma the grid reports: PassModelSd, else max(posterior, SampleSd).
    double UncertaintySd(double tau_s) const;
};

// A north-up grid: node (i, j) at x0 + i * resolution, y0 + j * resolution; row j = 0 is the
// southernmost. Arrays are row-major (j * nx + i).
struct CubeGrid {
    double x0 = 0, y0 = 0, resolution_m = 0;
    std::int64_t i0 = 0, j0 = 0;  // global index of node (0, 0): x0 = i0 res, y0 = j0 res
    int nx = 0, ny = 0;
    std::vector<float> elevation_m;    // NaN = empty
    std::vector<float> uncertainty_m;  // 95 %, NaN = empty
    std::vector<float> density;        // soundings in the chosen hypothesis
    std::vector<float> hypotheses;     // number of hypotheses
    std::size_t size() const { return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny); }
};

struct CubeResult {
    CubeGrid grid;
    double median_depth_m = 0;
    double capture_distance_m = 0;  // at the median depth
    std::int64_t soundings_used = 0;
    std::int64_t soundings_rejected = 0;  // non-finite values or sigmas
    std::int64_t node_updates = 0;
    std::int64_t nodes_filled = 0;
    std::int64_t nodes_multiple = 0;  // nodes with more than one hypothesis
    std::int64_t hypotheses_total = 0;
    bool ok = false;
    std::string message;
};

// The auto resolution for a median depth (CubeConfig::resolution_depth_fraction and bounds).
double ResolutionFromDepth(double median_depth_m, const CubeConfig& config);

// The estimator of one node, exposed for tests: AddSounding in order, then Flush, then
// Choose.
class CubeNode {
public:
    // Offers a sounding already propagated to the node (height, variance at the node).
    // measured_variance: the sounding's own variance at the node without C&M's distance growth
    // (sigma_v^2 + the slope term; NaN = unknown: the node uncertainty then takes the grown
    // variance as the error's).
    void Add(double z,
             double variance,
             const CubeConfig& config,
             double common_variance = std::numeric_limits<double>::quiet_NaN(),
             float time_s = 0,
             double measured_variance = std::numeric_limits<double>::quiet_NaN());
    // Empties the median queue into the hypotheses.
    void Flush(const CubeConfig& config);
    const std::vector<CubeHypothesis>& hypotheses() const { return hyps_; }
    // The hypothesis closest to `reference` (NaN: the densest); -1 if none.
    int Choose(double reference) const;
    // A sounding that left the median queue: the Kalman update of the closest hypothesis, or a
    // new one (RunCube keeps the queues itself, a band of nodes at a time).
    void Update(double z,
                double variance,
                const CubeConfig& config,
                double common_variance = std::numeric_limits<double>::quiet_NaN(),
                float time_s = 0,
                double measured_variance = std::numeric_limits<double>::quiet_NaN());

    // A queued sounding: height, variance at the node, common variance, time, own variance.
    struct Queued {
        float z, variance, common_variance, time_s, measured_variance;
    };

private:
    std::vector<Queued> queue_;  // sorted by z
    std::vector<CubeHypothesis> hyps_;
};

// Grids the soundings. Fails (ok = false, message) without soundings or when the grid would
// exceed max_nodes; preconditions: config.Validate() is empty.
// Nodes lie on one lattice for every run at a resolution: node (i, j) of the grid is the global
// node (i0 + i, j0 + j) at ((i0 + i) res, (j0 + j) res), and the predicted surface's cells are
// global too (cell a covers [a c - res / 2, (a + 1) c - res / 2), c = predicted_surface_cells
// res), so a tile of the grid (RunCubeTile) computes its nodes from the same numbers.
CubeResult RunCube(const std::vector<CubeSounding>& soundings, const CubeConfig& config);

// A rectangle of global nodes (RunCube's lattice): i in [i0, i1), j in [j0, j1).
struct CubeNodeRange {
    std::int64_t i0 = 0, j0 = 0, i1 = 0, j1 = 0;
    std::int64_t nx() const { return i1 - i0; }
    std::int64_t ny() const { return j1 - j0; }
};

// The whole survey's grid as RunCube lays it out (resolution, node range), without gridding;
// ok = false with RunCube's message where RunCube would fail. result.grid has the geometry and
// no layers; median_depth_m and capture_distance_m are set.
CubeResult LayOutCube(const std::vector<CubeSounding>& soundings, const CubeConfig& config);

// How far beyond a tile's nodes the soundings that decide them can lie, m: the largest capture
// distance, two predicted-surface cells (a sounding's cell and the neighbours of its gradient)
// and kLocale's neighbourhood. A tile given soundings this far around its core computes every
// core node as RunCube does.
double CubeTileReach(double resolution_m, const CubeConfig& config);

// One tile of the grid: the nodes of `core` from the soundings whose predicted-surface cell lies
// within `overlap_m` of the core (>= CubeTileReach), taken in input order. Every node equals
// RunCube's node at the same global index, bit for bit (tests/processor/hydro/cube_tile_test).
// The grid returned is the core (x0 = core.i0 res, nx = core.nx()); its counters count the
// core's nodes (node_updates: the soundings the core's nodes took, so that tiles that cover the
// survey once add up to RunCube's; soundings_used: those the tile read, halo included).
// Preconditions: config.Validate() is empty, config.resolution_m > 0 (the whole survey's:
// LayOutCube), overlap_m >= CubeTileReach(resolution_m, config), a non-empty core. Fails (ok =
// false) when the tile would exceed max_nodes; a tile without soundings is ok with every node
// empty. `survey` is the whole survey's node range (LayOutCube): the tile's own nodes stay inside
// it.
CubeResult RunCubeTile(const std::vector<CubeSounding>& soundings,
                       const CubeConfig& config,
                       const CubeNodeRange& core,
                       const CubeNodeRange& survey,
                       double overlap_m);

// RunCube's message for a result (the grid, the median depth, what CUBE did).
std::string DescribeCube(const CubeResult& result);

// Whether CUBE takes a sounding (finite, positive vertical sigma, finite depth); RunCube counts
// the others in soundings_rejected.
bool CubeTakes(const CubeSounding& sounding);

// LayOutCube over soundings given one at a time in input order (Add), without holding them:
// Finish gives LayOutCube's result for the soundings added (the median depth from their depths,
// 4 bytes a sounding, the extent, soundings_rejected and soundings_used). Decision 035.
class CubeLayout {
public:
    void Reserve(std::size_t n) { depths_.reserve(n); }
    void Add(const CubeSounding& sounding);
    CubeResult Finish(const CubeConfig& config);

private:
    std::vector<float> depths_;
    double min_x_ = std::numeric_limits<double>::max(), min_y_ = min_x_;
    double max_x_ = -min_x_, max_y_ = -min_x_;
    std::int64_t rejected_ = 0;
};

// The global predicted-surface cell (cube.hpp: cell a covers [a c - res / 2, (a + 1) c - res / 2),
// c = predicted_surface_cells res) of coordinate x (an easting or a northing), as RunCube takes
// it. x finite.
std::int64_t CubeCellIndex(double x, double resolution_m, const CubeConfig& config);

// The rows of predicted-surface cells, first .. last, whose soundings RunCubeTile reads for the
// node rows [j0, j1) with `overlap_m` (the same arithmetic).
struct CubeCellRows {
    std::int64_t first = 0, last = -1;
};
CubeCellRows CubeTileCellRows(std::int64_t j0,
                              std::int64_t j1,
                              double resolution_m,
                              const CubeConfig& config,
                              double overlap_m);

// A band of whole node rows of the survey for RunCubeTile, and the cell rows of its soundings.
struct CubeBand {
    CubeNodeRange core;
    CubeCellRows cells;
    std::int64_t soundings = 0;  // in those cell rows (halo included)
};

// The survey's node rows (layout: LayOutCube's grid) cut into bands of whole rows, in order,
// each reading at most max_soundings soundings and holding at most max_nodes nodes where one
// predicted-surface cell's rows allow it (a band is never less than a cell of rows, nor than a
// node row). `cell_soundings[b - first_cell]`: the soundings CUBE takes in cell row b (none
// outside). Decision 035: CUBE by bands holds a band's soundings and nodes, not the survey's.
std::vector<CubeBand> PlanCubeBands(const CubeGrid& layout,
                                    std::int64_t first_cell,
                                    const std::vector<std::int64_t>& cell_soundings,
                                    const CubeConfig& config,
                                    double overlap_m,
                                    std::int64_t max_soundings,
                                    std::int64_t max_nodes);

}  // namespace pitmap::proc::hydro
