// SPDX-License-Identifier: MIT
// Backscatter mosaic: the 83P per-beam intensities as relative seabed backscatter in dB,
// corrected for range and incidence, gridded on the DEM's grid (issue 17 item 6).
//
// Per sounding (sonar equation, Lurton 2010 "An Introduction to Underwater Acoustics" §8, with
// the head's gain and source level unknown and constant: the result is relative dB):
//   level_db   = 20 log10(I)                    (the 83P intensity is an amplitude)
//   range_db   = level_db + k log10(R) + 2 a R  (two-way spreading, k = 40 for spherical, and
//                                               two-way absorption, a one-way dB/m)
//   incidence  theta = acos(-u . n): u the unit vector from the transducer to the sounding, n
//              the upward normal of the DEM at the sounding's node (central differences)
//   corrected  = range_db - AR(theta) + AR(reference_angle)
// AR is the angular response: kLambert 10 log10(cos^2 theta) (Lambert's law), kEmpirical the
// mean range_db of all soundings in incidence bins (MB-System mbbackangle's idea: the survey's
// own average angular response, which also removes a specular lobe near normal incidence that
// Lambert's law lacks and any footprint-area or beam-pattern term that goes with the angle),
// kNone none. Bins with fewer than min_bin_soundings take the value interpolated between their
// neighbours. A plain bin mean mixes the seabed into AR wherever the materials seen differ
// with the angle (a line whose nadir runs over mud and whose outer beams reach gravel), so
// the empirical response is then refined empirical_iterations times, each time as the bin
// mean of each sounding's level minus the corrected mean of its node: a node seen at several
// angles (overlapping lines) tells the angle's effect apart from its own material, and a node
// seen at one angle only leaves the response as it was. Referencing to reference_angle_deg keeps
// the values those of that incidence. Grid: each sounding goes to its nearest node; a node holds
// the mean dB of its soundings (a geometric mean of the amplitudes: speckle's outliers weigh less),
// NaN when none. Intensities 0 (none) and 65535 (saturated) are not used and are counted. Pure
// code; RunMosaic is reentrant and single-threaded.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace pitmap::proc::hydro {

enum class AngularCorrection { kNone = 0, kLambert, kEmpirical };
const char* ToString(AngularCorrection a);  // "none", "lambert", "empirical"

struct MosaicConfig {
    double spreading_db_per_decade = 40.0;  // k: 40 = two-way spherical spreading (20 log R each
                                            // way); 40 minus the slope of a head's own TVG
    // a, one way: Francois & Garrison (1982) pure-water term at the Delta T's 260 kHz in fresh
    // water at 10 degC (a flooded pit has no boric acid or MgSO4 relaxation): 0.021 dB/m.
    double absorption_db_per_m = 0.021;
    AngularCorrection angular = AngularCorrection::kEmpirical;
    double reference_angle_deg = 45.0;  // corrected values are those at this incidence
    double angle_bin_deg = 1.0;         // empirical angular response bins
    int min_bin_soundings = 30;         // fewer: the bin is interpolated from its neighbours
    int empirical_iterations = 3;       // refinements of the empirical response (0 = bin mean)
    double max_incidence_deg = 80.0;    // soundings beyond are not used (grazing, ill-defined)

    std::vector<std::string> Validate() const;
};

// The soundings, struct of arrays, in the grid's horizontal coordinates (UTM, m).
struct MosaicSoundings {
    std::vector<double> x, y;
    std::vector<std::uint16_t> intensity;   // raw 83P value; 0 = none, 65535 = saturated
    std::vector<float> range_m;             // slant range transducer -> sounding
    std::vector<Eigen::Vector3f> beam_dir;  // unit, transducer -> sounding, grid axes (z up)
    std::size_t size() const { return x.size(); }
};

// The DEM the mosaic is gridded on (its geometry) and whose slopes give the incidence.
struct MosaicGrid {
    double x0 = 0, y0 = 0;  // centre of node (0, 0), the south-west one
    double resolution_m = 0;
    int nx = 0, ny = 0;
    const std::vector<float>* elevation_m = nullptr;  // nx * ny, row j = 0 south; NaN = empty
};

// The angular response applied: value per incidence bin (centre (k + 0.5) * bin_deg).
struct AngularResponse {
    double bin_deg = 1.0;
    std::vector<double> level_db;      // AR per bin
    std::vector<std::int64_t> counts;  // soundings per bin (empirical; 0 for Lambert)
    // AR at an incidence (linear between bin centres, constant beyond the end ones).
    double At(double incidence_deg) const;
};

struct MosaicResult {
    bool ok = false;
    std::string message;
    std::vector<float> corrected_db;    // nx * ny, mean corrected dB per node, NaN = none
    std::vector<float> uncorrected_db;  // nx * ny, mean 20 log10(I) per node (no correction)
    std::vector<float> count;           // soundings per node
    AngularResponse response;
    std::int64_t soundings_in = 0;
    std::int64_t used = 0;
    std::int64_t no_intensity = 0;  // intensity 0
    std::int64_t saturated = 0;     // intensity 65535
    std::int64_t outside_grid = 0;
    std::int64_t beyond_incidence = 0;  // incidence > max_incidence_deg
    std::int64_t nodes_filled = 0;
    double median_incidence_deg = 0;
    double corrected_p05_db = 0, corrected_p95_db = 0;  // spread of the filled nodes
};

// Maths, exposed for tests.
double IntensityDb(std::uint16_t intensity);  // 20 log10(I); I >= 1
// k log10(R) + 2 a R: what the water took from the echo, dB (R > 0).
double RangeLossDb(double range_m, const MosaicConfig& c);
// Incidence angle, degrees, of a beam (unit, transducer -> seabed) on a surface with an upward
// unit normal; 90 for a beam that grazes or meets the surface from below.
double IncidenceDeg(const Eigen::Vector3d& beam_dir, const Eigen::Vector3d& normal_up);
// Upward unit normal of the DEM at node (i, j) from central differences of the elevation (a
// one-sided difference at the edges or next to an empty node; vertical with no neighbour).
Eigen::Vector3d DemNormal(const MosaicGrid& g, int i, int j);
// 10 log10(cos^2 theta) sampled on the bins.
AngularResponse LambertResponse(double bin_deg, double max_incidence_deg);
// Mean of level_db per incidence bin over every sounding, thin bins interpolated.
AngularResponse EstimateAngularResponse(const std::vector<float>& level_db,
                                        const std::vector<float>& incidence_deg,
                                        const MosaicConfig& c);

// One refinement of an angular response: the bin mean of level_db[j] minus the mean corrected
// level of node[j] (level - AR) over its soundings; soundings with node[j] >= num_nodes or a
// NaN level are skipped.
AngularResponse RefineAngularResponse(const AngularResponse& response,
                                      const std::vector<float>& level_db,
                                      const std::vector<float>& incidence_deg,
                                      const std::vector<std::uint32_t>& node,
                                      std::size_t num_nodes,
                                      const MosaicConfig& c);

// Preconditions: config.Validate() is empty; every array of `s` has s.size() entries. The
// soundings are taken by value and released after the first pass (~34 bytes each, 200 MB on
// bejanca): pass them with std::move where the caller has no further use for them.
MosaicResult RunMosaic(MosaicSoundings s, const MosaicGrid& g, const MosaicConfig& config);

// RunMosaic over the soundings given a block at a time, in order (decision 035): Add levels a
// block (its range-corrected levels, incidences and nodes: 12 bytes a sounding kept, the blocks'
// soundings not), Finish the angular response and the nodes' means: RunMosaic's result bit for
// bit (RunMosaic is it with one block). `g` (and its elevation) must outlive it.
class MosaicByBlocks {
public:
    MosaicByBlocks(const MosaicGrid& g, const MosaicConfig& config);
    ~MosaicByBlocks();
    MosaicByBlocks(const MosaicByBlocks&) = delete;
    MosaicByBlocks& operator=(const MosaicByBlocks&) = delete;
    void Reserve(std::size_t soundings);  // the soundings that will be added
    void Add(const MosaicSoundings& block);
    MosaicResult Finish();

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace pitmap::proc::hydro
