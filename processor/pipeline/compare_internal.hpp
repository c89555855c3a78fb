// SPDX-License-Identifier: MIT
// The parts of `pitmap compare` (compare_stage.hpp), one file each, and what they share:
//   compare_epoch.cpp           a products folder read and checked (Epoch), gridded again at
//                               another resolution, the two folders checked against each
//                               other, the navigation gate;
//   compare_stage_3d.cpp        the change along the normal on the soundings (M3C2) and on B's
//                               TSDF mesh;
//   compare_stage_products.cpp  the products: dod.tif, the regions' GeoJSON, change_points.ply,
//                               the capacity curves, and compare.json's records;
//   compare_design.cpp          each survey against a design surface;
//   compare_stage.cpp           RunCompare, which runs them in order, and the capacity of one
//                               survey; compare_series.cpp a series of surveys.
// Internal to the pipeline library: nothing here is part of its interface.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/result.hpp"
#include "processor/compare/capacity.hpp"
#include "processor/compare/change.hpp"
#include "processor/compare/change_mesh.hpp"
#include "processor/compare/design.hpp"
#include "processor/compare/m3c2.hpp"
#include "processor/compare/registration.hpp"
#include "processor/compare/surface.hpp"
#include "processor/pipeline/compare_stage.hpp"
#include "processor/pipeline/pipeline.hpp"

namespace pitmap::proc::pipeline::compare_detail {

using Log = std::function<void(const std::string&)>;

struct NavSigma {
    bool known = false;
    double horizontal_m = 0, vertical_m = 0, roll_pitch_deg = 0, yaw_deg = 0;  // 1-sigma
};

// One products folder, read and checked.
struct Epoch {
    std::string dir;
    std::string label;  // "A", "B"
    nlohmann::json summary;
    compare::SurfaceGrid surface;  // the surface compared (at the common resolution)
    compare::SurfaceGrid dem;      // dem.tif as read (its CUBE sigma for the 3D change)
    int epsg = 0;
    std::string horizontal_name, vertical_name, vertical_datum_key;
    double datum_height_m = 0;  // ellipsoidal height of the DEM's datum (0: ellipsoid)
    std::string site, start_utc, run_id;
    double water_level_m = 0;  // in the DEM's datum
    NavSigma nav;
};

// The 3D change along the normal and its record (compare.json change3d); m3c2 empty when not
// computed.
struct Change3d {
    nlohmann::json record = {{"computed", false}};
    std::optional<compare::M3c2Result> m3c2;
};

// The change on B's TSDF mesh and its record (compare.json change_mesh); mesh empty when not
// computed.
struct ChangeOnMesh {
    nlohmann::json record = {{"computed", false}};
    std::optional<compare::TriangleMesh> b;  // B's mesh in A's frame
    std::optional<compare::ChangeMeshResult> change;
};

// The navigation gate's record (compare.json registration.navigation_gate) and the quality
// gates that tripped (compare.json quality_gates).
struct NavigationGate {
    nlohmann::json record = {{"evaluated", false}};
    nlohmann::json gates = nlohmann::json::array();
};

// The change mesh's regions of one sign in total, as the 2.5D totals: random, ground offset and
// margin terms in quadrature, registration (one correction) and rims linearly.
struct Totals3d {
    int count = 0;
    double volume_m3 = 0, area_m2 = 0, u95_m3 = 0;
};

// Each survey against the design (empty when none is given).
struct DesignComparison {
    nlohmann::json record;                                               // compare.json design
    std::vector<std::pair<std::string, compare::DesignResult>> results;  // file name, result
};

// --- compare_epoch.cpp

// The median of v (NaN when empty).
double Median(std::vector<double> v);
// A survey's water level in dem.tif's vertical datum (datum_height_m: the datum's ellipsoidal
// height, 0 on the ellipsoid), from the folder's trajectory.
Expected<double> WaterLevelOf(const std::string& dir,
                              const nlohmann::json& summary,
                              double datum_height_m);
// Everything of a products folder but its survey model.
Expected<Epoch> ReadEpochProducts(const std::string& dir, const char* label);
// The survey model, whole: a damaged survey.pitmap is an error, not a comparison.
Status CheckSurvey(Epoch& e);
// ReadEpochProducts and CheckSurvey.
Expected<Epoch> ReadEpoch(const std::string& dir, const char* label);
// The survey of `e` gridded again at `resolution_m` (decision 030); its record in `record`.
Expected<compare::SurfaceGrid> RegridEpoch(Epoch& e,
                                           double resolution_m,
                                           const PipelineConfig& config,
                                           const Log& log,
                                           nlohmann::json& record);
// One CRS, one vertical datum, one site, and ground in common: else no comparison.
Status CheckComparable(const Epoch& a, const Epoch& b, const Log& log);
// The registration's correction against what the two surveys' navigation allows.
NavigationGate CheckNavigation(const Epoch& a,
                               const Epoch& b,
                               const compare::RegistrationResult& reg,
                               const CompareConfig& cfg);
// compare.json's inputs record of one survey.
nlohmann::json EpochInputJson(const Epoch& e);

// --- compare_stage_3d.cpp

// The 3D change along the normal on the soundings, where both folders have them.
Expected<Change3d> ComputeChange3d(const Epoch& a,
                                   const Epoch& b,
                                   const compare::RegistrationResult& reg,
                                   const CompareConfig& cfg,
                                   const Log& log);
// The change on B's TSDF mesh, where both folders have one.
Expected<ChangeOnMesh> ComputeChangeOnMesh(const Epoch& a,
                                           const Epoch& b,
                                           const compare::RegistrationResult& reg,
                                           const Change3d& c3,
                                           const CompareConfig& cfg,
                                           const Log& log);
// The change mesh's regions confirmed by the soundings' change along the normal.
void ConfirmMeshRegions(const Change3d& c3,
                        const CompareConfig& cfg,
                        const Log& log,
                        ChangeOnMesh& m);

// --- compare_stage_products.cpp

// `text` written to `path` through a partial file renamed over it.
Status WriteText(const std::string& path, const std::string& text);
nlohmann::json CapacityJson(const compare::CapacityResult& c);
// capacity.csv's text: level, depth below the water level, area, volume.
std::string CapacityCsv(const compare::CapacityResult& c);
// change_points.ply: M3C2's core points with their change, in the products' CRS.
Status WriteChangePoints(const std::string& path,
                         const compare::M3c2Result& r,
                         int epsg,
                         const std::string& crs_name);
// dod.tif: the change on A's grid.
Status WriteDod(const std::filesystem::path& C,
                const Epoch& a,
                const Epoch& b,
                const compare::ChangeResult& change);
// change_regions.geojson; returns the regions' records for compare.json.
Expected<nlohmann::json> WriteChangeRegions(const std::filesystem::path& C,
                                            int epsg,
                                            const compare::ChangeResult& change);
// The change mesh's regions of one sign in total.
Totals3d RegionTotals3d(const compare::ChangeMeshResult& r, int sign, double z95);
// change_regions_3d.geojson; returns compare.json's change_mesh.regions and the totals.
Expected<nlohmann::json> WriteChangeRegions3d(const std::filesystem::path& C,
                                              int epsg,
                                              const compare::TriangleMesh& b,
                                              const compare::ChangeMeshResult& r,
                                              double z95);
// capacity_a.csv, capacity_b.csv, capacity.svg.
Status WriteCapacity(const std::filesystem::path& C,
                     const compare::CapacityResult& cap_a,
                     const compare::CapacityResult& cap_b,
                     const std::string& datum);
nlohmann::json RegistrationJson(const compare::RegistrationResult& reg,
                                const CompareConfig& cfg,
                                const nlohmann::json& gate_record);
nlohmann::json ChangeJson(const compare::ChangeResult& change,
                          double resolution_m,
                          const nlohmann::json& regions);

// --- compare_design.cpp

// Each survey against the design (empty when none is given).
Expected<DesignComparison> CompareDesign(const std::vector<const Epoch*>& epochs,
                                         const CompareConfig& cfg,
                                         const Log& log);
// design_a.tif / design_b.tif: the survey against the design on the survey's grid.
Status WriteDesignTif(const std::filesystem::path& path,
                      const Epoch& e,
                      const compare::DesignResult& d);
// Survey A against the design alone.
Expected<int> RunDesignOnly(const std::string& a_dir,
                            const std::string& out_dir,
                            const CompareConfig& cfg,
                            const Log& log);

}  // namespace pitmap::proc::pipeline::compare_detail
