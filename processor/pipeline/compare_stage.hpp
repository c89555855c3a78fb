// SPDX-License-Identifier: MIT
// `pitmap compare A B --out C` (issue 37): two surveys of one site, A the earlier. Reads each
// products folder's summary.json (CRS, vertical datum, origin, site), dem.tif (elevation and
// its 95 % uncertainty), survey.pitmap (checked whole: a damaged survey is an error),
// trajectory.csv or else trajectory_ins.csv (the water level: the vehicle rides on the water)
// and, where there,
// trajectory_sigma.csv (the navigation's 1-sigma); registers B onto A on stable terrain
// (processor/compare/registration.hpp), computes the change (change.hpp) and each survey's
// capacity curve (capacity.hpp), and writes into C:
//   dod.tif                COG on A's grid, horizontal CRS only: bands difference (B - A, m),
//                          lod95 (m), significance (-1 loss, 0 no detectable change, +1 gain),
//                          region (id in change_regions.geojson, 0 none); NaN where not both
//   change_regions.geojson one feature per change region: MultiPolygon outline in A's CRS
//                          (the legacy "crs" member names its EPSG code), properties id, kind
//                          (cut, fill), area_m2, volume_m3, u95_m3, max_abs_difference_m,
//                          mean_lod95_m
//   capacity_a.csv, capacity_b.csv
//                          level_m (the DEM's vertical datum), depth_below_water_level_m,
//                          area_m2, volume_m3
//   capacity.svg           both capacity curves (volume and area against water level) as a plot
//   change_points.ply      with change3d and both folders' points_utm.ply: the 3D change along
//                          the local normal (processor/compare/m3c2.hpp) at A's core points:
//                          double x, y, z (A's CRS), float nx, ny, nz, distance_m (B - A along
//                          the normal, > 0 towards the water), lod95_m, slope_deg, char
//                          significance, uint n_a, n_b; NaN distance where too few soundings
//   change_mesh.ply, change_mesh.glb
//                          with change_mesh and both folders' mesh_utm.ply: B's TSDF mesh with
//                          the signed distance to A's mesh along its normal, the LoD95 and the
//                          significance per vertex (compare_stage_mesh.hpp)
//   design_a.tif, design_b.tif
//                          with a design surface: COG on each survey's grid, bands difference
//                          (survey - design, m), u95 (m), significance (+1 above the design, -1
//                          below, 0 on it within the survey's uncertainty)
//   compare.json           inputs, crs, registration (correction, its 1-sigma, residuals, the
//                          navigation gate), change (totals and regions), capacity, quality_gates
// Errors (nothing is written to C, the message names the folder and the problem): a missing
// product, a damaged survey.pitmap or dem.tif, different horizontal CRS, vertical datums or
// sites (metadata.site, when both name one), surfaces that do not overlap, a registration
// that cannot be solved, a survey that cannot be gridded again at the other's resolution (or
// comes out on another datum or CRS than its dem.tif: processed with another config).
// Surfaces of different resolution: the coarser survey is gridded again at the finer
// resolution from its own accepted soundings (survey.pitmap, through the grid stage's TPU and
// CUBE with `survey`'s settings) on the same lattice, and the registration, the DEM of
// difference use the two surfaces at that resolution; the capacity curves, a design comparison
// and the 3D change's CUBE sigmas keep each survey's own dem.tif (decision 030).
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/compare/change.hpp"
#include "processor/compare/change_mesh.hpp"
#include "processor/compare/design.hpp"
#include "processor/compare/m3c2.hpp"
#include "processor/compare/registration.hpp"
#include "processor/pipeline/pipeline.hpp"

namespace pitmap::proc::pipeline {

struct CompareConfig {
    compare::RegistrationConfig registration;
    compare::ChangeConfig change;
    bool change3d = true;  // also the 3D change along the normal on the soundings (M3C2)
    compare::M3c2Config m3c2;
    bool change_mesh = true;  // also the change on B's TSDF mesh (both folders' mesh_utm.ply)
    compare::ChangeMeshConfig mesh;
    double change_mesh_colour_scale_m = 0.5;  // change mesh: full colour at this distance, m
    // Keep a change mesh region only where half the soundings' measured core points within a
    // core spacing of it are significant with its sign, and a vertex only where the cores
    // within a core spacing do not contradict it (needs change3d; change_mesh.hpp).
    bool confirm_mesh_regions = true;
    double capacity_step_m = 0.25;  // capacity curve: a row every step, m
    // A design surface (the planned cut: a GeoTIFF of heights in the surveys' CRS and vertical
    // datum); "" none. With it each survey is compared with it (design_a.tif, design_b.tif,
    // compare.json design), and B may be left out (the design alone: RunCompare with b_dir "").
    std::string design_path;
    compare::DesignConfig design;
    // The gate: the correction may exceed what the two surveys' navigation allows (95 %) by
    // its own 95 % uncertainty at most.
    double gate_z95 = 1.96;
    // What the surveys were processed with (pitmap compare --config: its georef:, grid: and
    // vertical: sections): where their CUBE resolutions differ, the coarser survey is gridded
    // again with it at the finer one's resolution (compare/common_grid.hpp, decision 030).
    PipelineConfig survey;
    std::vector<std::string> Validate() const;
};

// Returns the number of quality gates that tripped (compare.json quality_gates), or an error.
// b_dir "" with config.design_path set: survey A against the design alone (design_a.tif and
// compare.json's inputs, crs, design).
Expected<int> RunCompare(const std::string& a_dir,
                         const std::string& b_dir,
                         const std::string& out_dir,
                         const CompareConfig& config,
                         const std::function<void(const std::string&)>& log);

// The capacity curve of one survey's products folder (issue 37 item 3), as pitmap compare finds
// it for each survey: dem.tif's elevation and the water level from `summary` (world_origin,
// vehicle, vertical_datum; the products' summary.json, possibly not yet saved) and
// trajectory.csv (else trajectory_ins.csv). Writes DIR/capacity.csv (as compare's
// capacity_a.csv) and returns summary.json's record: water_level_m, deepest_m,
// surveyed_area_m2, area_at_water_level_m2, volume_at_water_level_m3, step_m, file and
// rows_level_area_volume ([level_m, area_m2, volume_m3] every step_m from the deepest node up,
// and at the water level). Errors: no dem.tif or heights, no trajectory, a write failure.
Expected<nlohmann::json> SurveyCapacity(const std::string& dir,
                                        const nlohmann::json& summary,
                                        double step_m);

// The change report of a comparison RunCompare wrote (two surveys): `report_program
// --compare out_dir` (C/report.html; docs/compare.md#report), run as `pitmap run` runs the survey
// report (report_program.hpp). An error when the program is not there or fails: the comparison
// itself is complete without it.
Status WriteCompareReport(const std::string& out_dir,
                          const std::string& report_program,
                          const std::function<void(const std::string&)>& log);

// More than two surveys of one site (issue 37 item 1): `dirs` in time order (each folder's
// summary.json metadata.survey_start_utc must come after the one before, else an error naming
// the folder out of order; all in the first one's horizontal CRS, else an error naming the
// folder), each consecutive pair compared by RunCompare into OUT/NN_<A>_to_<B> (NN from 01; A
// and B the folders' names), then OUT/series.json and OUT/series.csv: per interval the
// folders, dates, cut and fill with their U95, net (fill + cut; U95 the two in quadrature) and
// the cumulative net since the first survey (U95: the intervals' in quadrature: each interval
// has its own registration and the surveys' errors), and each interval's gates. Returns the
// number of quality gates that tripped over all intervals. A single `dirs` entry that is a file
// is a list of folders, one a line ('#' comments, blank lines skipped; relative to the file).
Expected<int> RunCompareSeries(const std::vector<std::string>& dirs,
                               const std::string& out_dir,
                               const CompareConfig& config,
                               const std::function<void(const std::string&)>& log);

}  // namespace pitmap::proc::pipeline
