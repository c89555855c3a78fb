// SPDX-License-Identifier: MIT
#include "processor/pipeline/compare_stage.hpp"

#include <time.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "common/byte_io.hpp"
#include "common/formats/ply.hpp"
#include "common/formats/replace_file.hpp"
#include "common/formats/trajectory_csv.hpp"
#include "common/peak_memory.hpp"
#include "processor/compare/capacity.hpp"
#include "processor/compare/common_grid.hpp"
#include "processor/hydro/cube.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/io/products.hpp"
#include "processor/pipeline/compare_stage_mesh.hpp"
#include "processor/pipeline/internal.hpp"
#include "processor/pipeline/report_program.hpp"
#include "processor/survey/survey_file.hpp"

namespace pitmap::proc::pipeline {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

struct NavSigma {
    bool known = false;
    double horizontal_m = 0, vertical_m = 0, roll_pitch_deg = 0, yaw_deg = 0;  // 1-sigma
};

// One products folder, read and checked.
struct Epoch {
    std::string dir;
    std::string label;  // "A", "B"
    json summary;
    compare::SurfaceGrid surface;  // the surface compared (at the common resolution)
    compare::SurfaceGrid dem;      // dem.tif as read (its CUBE sigma for the 3D change)
    int epsg = 0;
    std::string horizontal_name, vertical_name, vertical_datum_key;
    double datum_height_m = 0;  // ellipsoidal height of the DEM's datum (0: ellipsoid)
    std::string site, start_utc, run_id;
    double water_level_m = 0;  // in the DEM's datum
    NavSigma nav;
};

double Median(std::vector<double> v) {
    if (v.empty()) return std::nan("");
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

// Wall and process CPU seconds of each part of a comparison (compare.json
// timings_wall_cpu_s; CPU time says what a part costs when other work shares the cores), and
// the process's peak resident memory at the end.
class Laps {
public:
    void Lap(const char* name) {
        const auto wall = std::chrono::steady_clock::now();
        const double cpu = Cpu();
        record_[name] = {std::chrono::duration<double>(wall - wall_).count(), cpu - cpu_};
        wall_ = wall;
        cpu_ = cpu;
    }
    json Record() const {
        double wall = 0, cpu = 0;
        for (const auto& [name, v] : record_.items()) {
            wall += v[0].get<double>();
            cpu += v[1].get<double>();
        }
        return {{"timings_wall_cpu_s", record_},
                {"seconds", wall},
                {"cpu_seconds", cpu},
                {"peak_rss_mb", PeakRssMb()}};
    }

private:
    static double Cpu() {
        timespec ts{};
        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
        return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
    }
    json record_ = json::object();
    std::chrono::steady_clock::time_point wall_ = std::chrono::steady_clock::now();
    double cpu_ = Cpu();
};

// The navigation's median 1-sigma from trajectory_sigma.csv (absent: unknown).
Expected<NavSigma> ReadNavSigma(const std::string& path) {
    NavSigma s;
    std::ifstream in(path);
    if (!in) return s;
    std::string line;
    if (!std::getline(in, line)) return Error{path + ": empty"};
    std::vector<std::string> names;
    {
        std::stringstream ss(line);
        for (std::string c; std::getline(ss, c, ',');) names.push_back(c);
    }
    const auto col = [&](const char* n) {
        const auto it = std::find(names.begin(), names.end(), n);
        return it == names.end() ? -1 : static_cast<int>(it - names.begin());
    };
    const int ie = col("sigma_east_m"), in_ = col("sigma_north_m"), iu = col("sigma_up_m"),
              ir = col("sigma_roll_deg"), ip = col("sigma_pitch_deg"), iy = col("sigma_yaw_deg");
    if (ie < 0 || in_ < 0 || iu < 0 || ir < 0 || ip < 0 || iy < 0)
        return Error{path +
                     ": needs sigma_east_m, sigma_north_m, sigma_up_m, sigma_roll_deg, "
                     "sigma_pitch_deg, sigma_yaw_deg"};
    std::vector<double> h, v, rp, y;
    while (std::getline(in, line)) {
        std::vector<double> f;
        std::stringstream ss(line);
        for (std::string c; std::getline(ss, c, ',');) f.push_back(std::strtod(c.c_str(), nullptr));
        if (static_cast<int>(f.size()) < static_cast<int>(names.size())) continue;
        h.push_back(std::sqrt(0.5 * (f[ie] * f[ie] + f[in_] * f[in_])));
        v.push_back(f[iu]);
        rp.push_back(std::max(f[ir], f[ip]));
        y.push_back(f[iy]);
    }
    if (h.empty()) return Error{path + ": no rows"};
    s.known = true;
    s.horizontal_m = Median(h);
    s.vertical_m = Median(v);
    s.roll_pitch_deg = Median(rp);
    s.yaw_deg = Median(y);
    return s;
}

// A survey's water level in dem.tif's vertical datum (datum_height_m: the datum's ellipsoidal
// height, 0 on the ellipsoid): the vehicle rides on the water, its INS point
// ins_height_above_waterline_m above it; the median height of trajectory.csv (else
// trajectory_ins.csv).
Expected<double> WaterLevelOf(const std::string& dir, const json& summary, double datum_height_m) {
    const std::string traj_name =
        fs::exists(fs::path(dir) / "trajectory.csv") ? "trajectory.csv" : "trajectory_ins.csv";
    auto traj = formats::ReadTrajectoryCsv((fs::path(dir) / traj_name).string());
    if (!traj) return traj.error();
    if (traj->rows.empty()) return Error{traj_name + " has no poses"};
    std::vector<double> z;
    for (const auto& r : traj->rows) z.push_back(r.position_world_m.z());
    double above = 0;
    if (summary.contains("vehicle") && summary["vehicle"].is_object() &&
        summary["vehicle"].value("ins_height_above_waterline_m", json()).is_number()) {
        above = summary["vehicle"]["ins_height_above_waterline_m"].get<double>();
    }
    if (!summary.contains("world_origin") || !summary["world_origin"].is_object())
        return Error{"summary.json has no world_origin"};
    const double origin_h = summary["world_origin"].value("height_m", 0.0);
    return origin_h + Median(z) - above - datum_height_m;
}

// Everything of a products folder but its survey model (CheckSurvey, or RegridEpoch which
// loads it to grid it again).
Expected<Epoch> ReadEpochProducts(const std::string& dir, const char* label) {
    Epoch e;
    e.dir = dir;
    e.label = label;
    const std::string who = std::string(label) + " (" + dir + ")";
    if (!fs::is_directory(dir)) return Error{who + ": not a products folder"};
    // The trajectory after SLAM, else the INS's (pitmap run --no-slam, pitmap georef).
    const std::string traj_name =
        fs::exists(fs::path(dir) / "trajectory.csv") ? "trajectory.csv" : "trajectory_ins.csv";
    for (const char* f : {"summary.json", "dem.tif", "survey.pitmap", traj_name.c_str()}) {
        if (!fs::exists(fs::path(dir) / f)) {
            return Error{who + ": missing product " + f +
                         " (pitmap run, or pitmap grid for dem.tif, writes it)"};
        }
    }
    auto summary = io::ReadSummaryJson((fs::path(dir) / "summary.json").string());
    if (!summary) return Error{who + ": " + summary.error().message};
    e.summary = std::move(*summary);
    const json& s = e.summary;
    if (!s.is_object() || !s.contains("world_origin") || !s.contains("utm"))
        return Error{who +
                     ": summary.json has no world_origin or utm (not written by pitmap run?)"};
    auto dem = io::ReadGrid((fs::path(dir) / "dem.tif").string());
    if (!dem) return Error{who + ": " + dem.error().message};
    const io::GridLayer* elevation = nullptr;
    const io::GridLayer* uncertainty = nullptr;
    const io::GridLayer* density = nullptr;
    for (const auto& l : dem->grid.layers) {
        if (l.name == "elevation") elevation = &l;
        if (l.name == "uncertainty") uncertainty = &l;
        if (l.name == "density") density = &l;
    }
    if (elevation == nullptr || uncertainty == nullptr)
        return Error{who + ": dem.tif has no elevation and uncertainty bands"};
    e.epsg = dem->horizontal_epsg;
    e.horizontal_name = dem->horizontal_name;
    e.vertical_name = dem->vertical_name;
    if (e.epsg == 0) return Error{who + ": dem.tif has no EPSG-coded horizontal CRS"};
    compare::SurfaceGrid& g = e.surface;
    g.x0 = dem->grid.x0;
    g.y0 = dem->grid.y0;
    g.resolution_m = dem->grid.resolution_m;
    g.nx = dem->grid.nx;
    g.ny = dem->grid.ny;
    g.z_m = elevation->values;
    g.sigma_m = uncertainty->values;
    for (float& v : g.sigma_m) v /= 1.96f;  // the band is the 95 % uncertainty
    // Soundings per node: the registration leaves out the nodes few soundings made.
    if (density != nullptr) g.density = density->values;
    if (g.CountFilled() == 0) return Error{who + ": dem.tif holds no heights"};
    e.dem = g;
    // Vertical datum: summary.json's record of the grid stage.
    if (s.contains("vertical_datum") && s["vertical_datum"].is_object()) {
        const json& v = s["vertical_datum"];
        e.vertical_datum_key =
            v.value("vertical_crs", std::string()) + " / " + v.value("datum", std::string());
        if (v.value("datum", std::string("ellipsoid")) != "ellipsoid") {
            const json& h = v.value("mean_datum_height_m", json());
            e.datum_height_m = h.is_number() ? h.get<double>() : 0.0;
        }
    } else {
        e.vertical_datum_key = e.vertical_name;
    }
    if (s.contains("metadata") && s["metadata"].is_object()) {
        e.site = s["metadata"].value("site", std::string());
        e.start_utc = s["metadata"].value("survey_start_utc", std::string());
    }
    auto level = WaterLevelOf(dir, s, e.datum_height_m);
    if (!level) return Error{who + ": " + level.error().message};
    e.water_level_m = *level;
    auto nav = ReadNavSigma((fs::path(dir) / "trajectory_sigma.csv").string());
    if (!nav) return Error{who + ": " + nav.error().message};
    e.nav = *nav;
    return e;
}

// The survey model, whole: a damaged survey.pitmap is an error, not a comparison.
Status CheckSurvey(Epoch& e) {
    auto model = survey::LoadSurvey((fs::path(e.dir) / survey::kSurveyFileName).string());
    if (!model) return Error{e.label + " (" + e.dir + "): " + model.error().message};
    e.run_id = model->run_id;
    return Ok{};
}

Expected<Epoch> ReadEpoch(const std::string& dir, const char* label) {
    auto e = ReadEpochProducts(dir, label);
    if (!e) return e;
    if (auto st = CheckSurvey(*e); !st) return st.error();
    return e;
}

// The survey of `e` gridded again at `resolution_m` (decision 030): survey.pitmap loaded whole
// (a damaged one is an error) and georeferenced on its newest trajectory, its accepted
// soundings through the grid stage's CUBE input (TPU, UTM, the products' datum) and CUBE at
// that resolution on the global lattice (node i at i x resolution, as every CUBE run). The
// surface filter is not run again: the soundings are those the survey's own run accepted.
// Its record goes into `record` (compare.json resolution_match.regrid).
Expected<compare::SurfaceGrid> RegridEpoch(Epoch& e,
                                           double resolution_m,
                                           const PipelineConfig& config,
                                           const std::function<void(const std::string&)>& log,
                                           json& record) {
    const std::string who = e.label + " (" + e.dir + ")";
    const auto say = [&](const std::string& m) { log("compare: " + e.label + ": " + m); };
    std::optional<detail::SurveyCubeInput> in;
    {
        auto s = detail::LoadSurvey(e.dir, config, detail::StartFrom::kLatest, say);
        if (!s) return Error{who + ": " + s.error().message};
        e.run_id = s->model.run_id;
        auto cube_input = detail::CubeInputOf(*s, config, say);
        if (!cube_input) return Error{who + ": gridding again: " + cube_input.error().message};
        in = std::move(*cube_input);
    }  // the survey and its view are freed before CUBE
    const json& d = in->datum_record;
    const std::string key =
        d.value("vertical_crs", std::string()) + " / " + d.value("datum", std::string());
    if (key != e.vertical_datum_key || in->utm_epsg != e.epsg) {
        return Error{who + ": gridded again with this comparison's config its soundings are on " +
                     key + " (EPSG " + std::to_string(in->utm_epsg) + "), its dem.tif on " +
                     e.vertical_datum_key + " (EPSG " + std::to_string(e.epsg) +
                     "): give pitmap compare the config the survey was processed with (--config)"};
    }
    hydro::CubeConfig cube = config.grid.cube;
    cube.resolution_m = resolution_m;
    const hydro::CubeResult r = hydro::RunCube(in->soundings, cube);
    if (!r.ok) return Error{who + ": gridding again: " + r.message};
    compare::SurfaceGrid g;
    g.x0 = r.grid.x0;
    g.y0 = r.grid.y0;
    g.resolution_m = r.grid.resolution_m;
    g.nx = r.grid.nx;
    g.ny = r.grid.ny;
    g.z_m = r.grid.elevation_m;
    g.sigma_m = r.grid.uncertainty_m;
    for (float& v : g.sigma_m) v /= 1.96f;  // as dem.tif's 95 % band
    g.density = r.grid.density;             // as dem.tif's density band (the registration's nodes)
    record = {{"survey", e.label == "A" ? "a" : "b"},
              {"resolution_m", resolution_m},
              {"soundings", in->soundings.size()},
              {"nodes_filled", r.nodes_filled},
              {"nodes_filled_before", e.surface.CountFilled()},
              {"message", r.message}};
    say("gridded again at " + std::to_string(resolution_m).substr(0, 5) + " m: " + r.message);
    return g;
}

json RingJson(const std::vector<Eigen::Vector2d>& ring) {
    json r = json::array();
    for (const auto& p : ring) {
        r.push_back({std::round(p.x() * 1000.0) / 1000.0, std::round(p.y() * 1000.0) / 1000.0});
    }
    return r;
}

json CapacityJson(const compare::CapacityResult& c) {
    return {{"water_level_m", c.water_level_m},
            {"deepest_m", c.min_height_m},
            {"surveyed_area_m2", c.surveyed_area_m2},
            {"area_at_water_level_m2", c.area_at_water_level_m2},
            {"volume_at_water_level_m3", c.volume_at_water_level_m3}};
}

Status WriteText(const std::string& path, const std::string& text) {
    return formats::WriteReplacing(path, [&](const std::string& partial) -> Status {
        std::ofstream out(partial, std::ios::binary | std::ios::trunc);
        out << text;
        out.close();
        if (!out) return Error{partial + ": write failed"};
        return Ok{};
    });
}

std::string CapacityCsv(const compare::CapacityResult& c) {
    std::string s = "level_m,depth_below_water_level_m,area_m2,volume_m3\n";
    char line[160];
    for (const auto& r : c.rows) {
        std::snprintf(line,
                      sizeof line,
                      "%.4f,%.4f,%.3f,%.3f\n",
                      r.level_m,
                      c.water_level_m - r.level_m,
                      r.area_m2,
                      r.volume_m3);
        s += line;
    }
    return s;
}

// The accepted soundings of points_utm.ply (status 0); empty when the file is not there.
Expected<std::vector<Eigen::Vector3d>> ReadSoundingsUtm(const std::string& dir) {
    const fs::path path = fs::path(dir) / "points_utm.ply";
    if (!fs::exists(path)) return std::vector<Eigen::Vector3d>{};
    auto ply = formats::ply::ReadMesh(path.string(), {"status"});
    if (!ply) return Error{dir + ": " + ply.error().message};
    std::vector<Eigen::Vector3d> out;
    out.reserve(ply->vertices.size());
    for (std::size_t i = 0; i < ply->vertices.size(); ++i) {
        if (ply->vertex_properties[0][i] == 0) out.push_back(ply->vertices[i]);
    }
    return out;
}

Status WriteChangePoints(const std::string& path,
                         const compare::M3c2Result& r,
                         int epsg,
                         const std::string& crs_name) {
    namespace ply = formats::ply;
    ply::Header h;
    h.comments = {"generated by pitmap compare",
                  "pitmap_crs_epsg " + std::to_string(epsg) + " 0",
                  "pitmap_crs " + crs_name,
                  "3D change along the local normal (M3C2) at A's core points: distance_m = B - A "
                  "along the normal (> 0 towards the water), lod95_m, significance -1 loss 0 none "
                  "+1 gain; NaN distance: too few soundings"};
    std::uint64_t n = r.cores.size();
    h.elements.push_back({"vertex",
                          n,
                          {{"x", ply::Type::kFloat64},
                           {"y", ply::Type::kFloat64},
                           {"z", ply::Type::kFloat64},
                           {"nx", ply::Type::kFloat32},
                           {"ny", ply::Type::kFloat32},
                           {"nz", ply::Type::kFloat32},
                           {"distance_m", ply::Type::kFloat32},
                           {"lod95_m", ply::Type::kFloat32},
                           {"slope_deg", ply::Type::kFloat32},
                           {"significance", ply::Type::kInt8},
                           {"n_a", ply::Type::kUInt32},
                           {"n_b", ply::Type::kUInt32}}});
    return formats::WriteReplacing(path, [&](const std::string& partial) -> Status {
        ply::Writer w(partial, h);
        for (const auto& c : r.cores) {
            ByteWriter& o = w.Record();
            for (int k = 0; k < 3; ++k) o.F64Le(c.position[k]);
            for (int k = 0; k < 3; ++k) o.F32Le(static_cast<float>(c.normal[k]));
            o.F32Le(c.distance_m);
            o.F32Le(c.lod95_m);
            o.F32Le(c.slope_deg);
            o.I8(static_cast<std::int8_t>(c.significance));
            o.U32Le(static_cast<std::uint32_t>(c.n_a));
            o.U32Le(static_cast<std::uint32_t>(c.n_b));
        }
        return w.Close();
    });
}

// capacity.svg: volume and water-surface area against water level for both surveys, the
// water levels dashed (a plain SVG: no plotting library needed to read it).
std::string CapacitySvg(const compare::CapacityResult& a,
                        const compare::CapacityResult& b,
                        const std::string& datum) {
    const double W = 900, H = 420, panel_w = 380, panel_h = 300, top = 50, left[2] = {80, 520};
    double lo = std::min(a.min_height_m, b.min_height_m);
    double hi = std::max(a.water_level_m, b.water_level_m);
    if (!(hi > lo)) hi = lo + 1;
    double vmax = 1, amax = 1;
    for (const auto* c : {&a, &b}) {
        for (const auto& r : c->rows) {
            vmax = std::max(vmax, r.volume_m3);
            amax = std::max(amax, r.area_m2);
        }
    }
    std::string svg;
    char buf[400];
    std::snprintf(buf,
                  sizeof buf,
                  "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" "
                  "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%%\" "
                  "height=\"100%%\" fill=\"white\"/>\n",
                  W,
                  H);
    svg += buf;
    const char* colour[2] = {"#1f77b4", "#d62728"};
    for (int p = 0; p < 2; ++p) {
        const double x0 = left[p], xmax = p == 0 ? vmax : amax;
        const auto X = [&](double v) { return x0 + panel_w * v / xmax; };
        const auto Y = [&](double level) { return top + panel_h * (hi - level) / (hi - lo); };
        std::snprintf(buf,
                      sizeof buf,
                      "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"none\" "
                      "stroke=\"black\"/>\n<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"middle\">%s"
                      "</text>\n<text x=\"%.1f\" y=\"%.1f\">0</text><text x=\"%.1f\" y=\"%.1f\" "
                      "text-anchor=\"end\">%.0f</text>\n",
                      x0,
                      top,
                      panel_w,
                      panel_h,
                      x0 + panel_w / 2,
                      top + panel_h + 35,
                      p == 0 ? "water volume (m3)" : "water surface area (m2)",
                      x0,
                      top + panel_h + 15,
                      x0 + panel_w,
                      top + panel_h + 15,
                      xmax);
        svg += buf;
        std::snprintf(buf,
                      sizeof buf,
                      "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"end\">%.2f</text><text x=\"%.1f\" "
                      "y=\"%.1f\" text-anchor=\"end\">%.2f</text>\n",
                      x0 - 4,
                      top + 4,
                      hi,
                      x0 - 4,
                      top + panel_h,
                      lo);
        svg += buf;
        for (int e = 0; e < 2; ++e) {
            const compare::CapacityResult& c = e == 0 ? a : b;
            std::string pts;
            for (const auto& r : c.rows) {
                std::snprintf(buf,
                              sizeof buf,
                              "%.1f,%.1f ",
                              X(p == 0 ? r.volume_m3 : r.area_m2),
                              Y(r.level_m));
                pts += buf;
            }
            svg += "<polyline fill=\"none\" stroke-width=\"2\" stroke=\"" + std::string(colour[e]) +
                   "\" points=\"" + pts + "\"/>\n";
            std::snprintf(buf,
                          sizeof buf,
                          "<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" stroke=\"%s\" "
                          "stroke-dasharray=\"4 3\"/>\n",
                          x0,
                          x0 + panel_w,
                          Y(c.water_level_m),
                          Y(c.water_level_m),
                          colour[e]);
            svg += buf;
        }
    }
    std::snprintf(buf,
                  sizeof buf,
                  "<text x=\"20\" y=\"25\">Capacity: water level (m, %s) against volume and "
                  "area; A blue, B red; dashed: each survey's water level (A %.0f m3, B %.0f m3)"
                  "</text>\n</svg>\n",
                  datum.c_str(),
                  a.volume_at_water_level_m3,
                  b.volume_at_water_level_m3);
    svg += buf;
    return svg;
}

// One CRS, one vertical datum, one site, and ground in common: else no comparison.
Status CheckComparable(const Epoch& a,
                       const Epoch& b,
                       const std::function<void(const std::string&)>& log) {
    if (a.epsg != b.epsg) {
        return Error{"compare: different horizontal CRS: A is " + a.horizontal_name + " (EPSG " +
                     std::to_string(a.epsg) + "), B " + b.horizontal_name + " (EPSG " +
                     std::to_string(b.epsg) + "); process both in one (config utm zone)"};
    }
    if (a.vertical_datum_key != b.vertical_datum_key) {
        return Error{"compare: different vertical datums: A in " + a.vertical_datum_key +
                     ", B in " + b.vertical_datum_key +
                     "; grid both to one (config vertical.datum)"};
    }
    if (!a.site.empty() && !b.site.empty() && a.site != b.site) {
        return Error{"compare: different sites: A is '" + a.site + "', B '" + b.site + "'"};
    }
    if (std::abs(a.surface.resolution_m - b.surface.resolution_m) > 1e-9) {
        log("compare: the grids differ in resolution (A " + std::to_string(a.surface.resolution_m) +
            " m, B " + std::to_string(b.surface.resolution_m) +
            " m): the coarser survey is gridded again at the finer resolution");
    }
    // Overlap before anything else: surveys of two places share no ground.
    const auto& A = a.surface;
    const auto& B = b.surface;
    const double ax1 = A.x0 + (A.nx - 1) * A.resolution_m, ay1 = A.y0 + (A.ny - 1) * A.resolution_m;
    const double bx1 = B.x0 + (B.nx - 1) * B.resolution_m, by1 = B.y0 + (B.ny - 1) * B.resolution_m;
    if (bx1 < A.x0 || B.x0 > ax1 || by1 < A.y0 || B.y0 > ay1) {
        char buf[320];
        std::snprintf(buf,
                      sizeof buf,
                      "compare: the surveys do not overlap: A covers E %.0f-%.0f N %.0f-%.0f, "
                      "B E %.0f-%.0f N %.0f-%.0f (%s); different sites?",
                      A.x0,
                      ax1,
                      A.y0,
                      ay1,
                      B.x0,
                      bx1,
                      B.y0,
                      by1,
                      a.horizontal_name.c_str());
        return Error{buf};
    }
    return Ok{};
}

// The 3D change along the normal and its record (compare.json change3d); m3c2 empty when not
// computed.
struct Change3d {
    json record = {{"computed", false}};
    std::optional<compare::M3c2Result> m3c2;
};

// The median 1-sigma of both CUBE surfaces' filled nodes.
double MedianSigma(const compare::SurfaceGrid& a, const compare::SurfaceGrid& b) {
    std::vector<double> sig;
    for (const auto* g : {&a, &b}) {
        for (float v : g->sigma_m) {
            if (std::isfinite(v)) sig.push_back(v);
        }
    }
    return Median(sig);
}

// What the soundings of a cylinder (or a mesh vertex) share: both CUBE surfaces' 1-sigma at
// the point, in quadrature (the median where a surface has none). Each survey's own dem.tif:
// the change along the normal does not depend on the grid the DoD is computed on (decision
// 030).
std::function<double(const Eigen::Vector3d&)> CommonSigma(const compare::SurfaceGrid& sa,
                                                          const compare::SurfaceGrid& sb) {
    const double sigma_median = MedianSigma(sa, sb);
    return [&sa, &sb, sigma_median](const Eigen::Vector3d& p) {
        double x = sa.SigmaAt(p.x(), p.y()), y = sb.SigmaAt(p.x(), p.y());
        if (!std::isfinite(x)) x = sigma_median;
        if (!std::isfinite(y)) y = sigma_median;
        return std::hypot(x, y);
    };
}

// The change on B's TSDF mesh and its record (compare.json change_mesh); mesh empty when not
// computed.
struct ChangeOnMesh {
    json record = {{"computed", false}};
    std::optional<compare::TriangleMesh> b;  // B's mesh in A's frame
    std::optional<compare::ChangeMeshResult> change;
};

Expected<ChangeOnMesh> ComputeChangeOnMesh(const Epoch& a,
                                           const Epoch& b,
                                           const compare::RegistrationResult& reg,
                                           const Change3d& c3,
                                           const CompareConfig& cfg,
                                           const std::function<void(const std::string&)>& log) {
    ChangeOnMesh out;
    if (!cfg.change_mesh) return out;
    auto ma = ReadMeshUtm(a.dir, a.epsg);
    if (!ma) return Error{"compare: A " + ma.error().message};
    auto mb = ReadMeshUtm(b.dir, b.epsg);
    if (!mb) return Error{"compare: B " + mb.error().message};
    if (!*ma || !*mb || (*ma)->triangles.empty() || (*mb)->triangles.empty()) {
        out.record["message"] = "mesh_utm.ply missing or empty in A or B: not computed";
        return out;
    }
    for (Eigen::Vector3d& p : (*mb)->vertices) p = reg.correction.Apply(p);
    // The soundings' change along the normal, where computed: what contradicts a vertex.
    std::optional<compare::SoundingsChange> soundings;
    if (c3.m3c2 && cfg.confirm_mesh_regions) {
        soundings.emplace();
        soundings->radius_m = cfg.m3c2.core_spacing_m;
        for (const auto& c : c3.m3c2->cores) {
            if (!std::isfinite(c.distance_m)) continue;
            soundings->position.push_back(c.position);
            soundings->distance_m.push_back(c.distance_m);
            soundings->significance.push_back(c.significance);
        }
    }
    out.change = compare::ComputeChangeMesh(**mb,
                                            **ma,
                                            reg.correction,
                                            reg.covariance,
                                            cfg.mesh,
                                            CommonSigma(a.dem, b.dem),
                                            soundings ? &*soundings : nullptr);
    out.b = std::move(**mb);
    log("compare: change mesh: " + out.change->message);
    out.record = {{"computed", true},
                  {"message", out.change->message},
                  {"vertices", out.b->vertices.size()},
                  {"measured", out.change->measured},
                  {"gain", out.change->gain},
                  {"loss", out.change->loss},
                  {"patches", out.change->patches},
                  {"patches_dropped", out.change->patches_dropped},
                  {"vetoed_by_soundings", out.change->vetoed_by_soundings},
                  {"grown", out.change->grown},
                  {"grow_lod_fraction", cfg.mesh.grow_lod_fraction},
                  {"grow_max_m", cfg.mesh.grow_max_m},
                  {"median_lod95_m", out.change->median_lod95_m},
                  {"normals_turned_over", out.change->flipped},
                  {"max_distance_m", cfg.mesh.max_distance_m},
                  {"colour_scale_m", cfg.change_mesh_colour_scale_m}};
    return out;
}

// The change mesh's regions confirmed by the soundings' change along the normal, where both
// were computed (change_mesh.hpp ConfirmRegionsBySoundings; compare.json
// change_mesh.regions_unconfirmed).
void ConfirmMeshRegions(const Change3d& c3,
                        const CompareConfig& cfg,
                        const std::function<void(const std::string&)>& log,
                        ChangeOnMesh& m) {
    if (!m.change || !c3.m3c2 || !cfg.confirm_mesh_regions) return;
    std::vector<Eigen::Vector3d> pos;
    std::vector<int> sig;
    for (const auto& c : c3.m3c2->cores) {
        if (!std::isfinite(c.distance_m)) continue;
        pos.push_back(c.position);
        sig.push_back(c.significance);
    }
    const std::size_t dropped =
        compare::ConfirmRegionsBySoundings(*m.b, pos, sig, cfg.m3c2.core_spacing_m, 0.5, *m.change);
    m.record["patches"] = m.change->patches;
    m.record["gain"] = m.change->gain;
    m.record["loss"] = m.change->loss;
    m.record["regions_unconfirmed"] = dropped;
    log("compare: change mesh: " + std::to_string(m.change->regions.size()) +
        " regions confirmed by the soundings' change along the normal, " + std::to_string(dropped) +
        " not (the two meshes differ where the soundings agree)");
}

// The 3D change's level of detection by slope class (compare.json change3d.by_slope).
json M3c2BySlope(const compare::M3c2Result& m3c2) {
    json by_slope = json::object();
    const std::pair<const char*, std::pair<double, double>> classes[] = {
        {"floor_0_20_deg", {0, 20}}, {"face_20_45_deg", {20, 45}}, {"wall_45_90_deg", {45, 91}}};
    for (const auto& [name, range] : classes) {
        std::vector<double> lods;
        std::size_t flagged = 0;
        for (const auto& c : m3c2.cores) {
            if (!std::isfinite(c.distance_m) || c.slope_deg < range.first ||
                c.slope_deg >= range.second)
                continue;
            lods.push_back(c.lod95_m);
            flagged += c.significance != 0;
        }
        by_slope[name] = {{"measured", lods.size()},
                          {"significant", flagged},
                          {"median_lod95_m", lods.empty() ? 0.0 : Median(lods)}};
    }
    return by_slope;
}

// The 3D change along the normal on the soundings, where both folders have them.
Expected<Change3d> ComputeChange3d(const Epoch& a,
                                   const Epoch& b,
                                   const compare::RegistrationResult& reg,
                                   const CompareConfig& cfg,
                                   const std::function<void(const std::string&)>& log) {
    Change3d out;
    if (!cfg.change3d) return out;
    auto pa = ReadSoundingsUtm(a.dir);
    if (!pa) return Error{"compare: A " + pa.error().message};
    auto pb = ReadSoundingsUtm(b.dir);
    if (!pb) return Error{"compare: B " + pb.error().message};
    if (pa->empty() || pb->empty()) {
        out.record["message"] = "points_utm.ply missing or empty in A or B: not computed";
        return out;
    }
    for (Eigen::Vector3d& p : *pb) p = reg.correction.Apply(p);
    out.m3c2 = compare::RunM3c2(*pa,
                                *pb,
                                reg.correction.pivot,
                                reg.correction,
                                reg.covariance,
                                cfg.m3c2,
                                CommonSigma(a.dem, b.dem));
    log("compare: 3D change: " + out.m3c2->message);
    out.record = {{"computed", true},
                  {"message", out.m3c2->message},
                  {"cores", out.m3c2->cores.size()},
                  {"measured", out.m3c2->measured},
                  {"significant", out.m3c2->significant},
                  {"isolated", out.m3c2->isolated},
                  {"not_planar", out.m3c2->not_planar},
                  {"core_spacing_m", cfg.m3c2.core_spacing_m},
                  {"projection_radius_m", cfg.m3c2.projection_radius_m},
                  {"by_slope", M3c2BySlope(*out.m3c2)}};
    return out;
}

// The navigation gate's record (compare.json registration.navigation_gate) and the quality
// gates that tripped (compare.json quality_gates).
struct NavigationGate {
    json record = {{"evaluated", false}};
    json gates = json::array();
};

json NavSigmaJson(const NavSigma& n) {
    return {{"horizontal_m", n.horizontal_m},
            {"vertical_m", n.vertical_m},
            {"roll_pitch_deg", n.roll_pitch_deg},
            {"yaw_deg", n.yaw_deg}};
}

// The navigation gate: the correction against what the two surveys' navigation allows.
NavigationGate CheckNavigation(const Epoch& a,
                               const Epoch& b,
                               const compare::RegistrationResult& reg,
                               const CompareConfig& cfg) {
    NavigationGate out;
    if (!(a.nav.known && b.nav.known)) {
        out.record["message"] = "trajectory_sigma.csv missing in A or B: not evaluated";
        return out;
    }
    const auto& T = reg.correction;
    const double th = T.translation_m.head<2>().norm();
    const double tz = std::abs(T.translation_m.z());
    const double yaw_deg = std::abs(T.rotation_rad.z()) * kRadToDeg;
    const double rp_deg = T.rotation_rad.head<2>().norm() * kRadToDeg;
    const double z = cfg.gate_z95;
    const double sig_th = std::hypot(reg.sigma(3), reg.sigma(4));
    const double nav_h = 2.4477 * std::hypot(a.nav.horizontal_m, b.nav.horizontal_m);
    const double nav_v = z * std::hypot(a.nav.vertical_m, b.nav.vertical_m);
    const double nav_yaw = z * std::hypot(a.nav.yaw_deg, b.nav.yaw_deg);
    const double nav_rp = 2.4477 * std::hypot(a.nav.roll_pitch_deg, b.nav.roll_pitch_deg);
    const double allow_h = nav_h + 2.4477 * sig_th;
    const double allow_v = nav_v + z * reg.sigma(5);
    const double allow_yaw = nav_yaw + z * reg.sigma(2) * kRadToDeg;
    const double allow_rp = nav_rp + 2.4477 * std::hypot(reg.sigma(0), reg.sigma(1)) * kRadToDeg;
    std::vector<std::string> beyond;
    char buf[160];
    if (th > allow_h) {
        std::snprintf(buf, sizeof buf, "horizontal %.3f m > %.3f m", th, allow_h);
        beyond.push_back(buf);
    }
    if (tz > allow_v) {
        std::snprintf(buf, sizeof buf, "vertical %.3f m > %.3f m", tz, allow_v);
        beyond.push_back(buf);
    }
    if (yaw_deg > allow_yaw) {
        std::snprintf(buf, sizeof buf, "yaw %.4f deg > %.4f deg", yaw_deg, allow_yaw);
        beyond.push_back(buf);
    }
    if (cfg.registration.estimate_roll_pitch && rp_deg > allow_rp) {
        std::snprintf(buf, sizeof buf, "roll/pitch %.4f deg > %.4f deg", rp_deg, allow_rp);
        beyond.push_back(buf);
    }
    std::string why;
    for (const auto& s : beyond) why += (why.empty() ? "" : ", ") + s;
    out.record = {{"evaluated", true},
                  {"tripped", !beyond.empty()},
                  {"allowed_horizontal_m", allow_h},
                  {"allowed_vertical_m", allow_v},
                  {"allowed_yaw_deg", allow_yaw},
                  {"allowed_roll_pitch_deg", allow_rp},
                  {"navigation_sigma", {{"a", NavSigmaJson(a.nav)}, {"b", NavSigmaJson(b.nav)}}},
                  {"beyond", why}};
    if (!beyond.empty()) {
        out.gates.push_back(
            {{"stage", "compare"},
             {"gate", "correction_beyond_navigation"},
             {"message",
              "the correction that registers B onto A is larger than the two surveys' "
              "navigation uncertainty allows (95 %): " +
                  why +
                  "; a datum, antenna or base-station error in one of them? The change is "
                  "computed after the correction"}});
    }
    return out;
}

// dod.tif: the change on A's grid.
Status WriteDod(const fs::path& C,
                const Epoch& a,
                const Epoch& b,
                const compare::ChangeResult& change) {
    io::GridRaster dod;
    dod.x0 = a.surface.x0;
    dod.y0 = a.surface.y0;
    dod.resolution_m = a.surface.resolution_m;
    dod.nx = a.surface.nx;
    dod.ny = a.surface.ny;
    dod.utm_zone = a.epsg % 100;
    dod.northern = a.epsg < 32700;
    if (!((a.epsg > 32600 && a.epsg <= 32660) || (a.epsg > 32700 && a.epsg <= 32760)))
        return Error{"compare: dod.tif: A's CRS is not WGS 84 / UTM (EPSG " +
                     std::to_string(a.epsg) + ")"};
    dod.horizontal_only = true;
    using K = io::GridBandKind;
    dod.layers = {{"difference", "metre", change.difference_m, K::kContinuous},
                  {"lod95", "metre", change.lod95_m, K::kContinuous},
                  {"significance", "class", change.significance, K::kCount},
                  {"region", "id", change.region, K::kCount}};
    dod.metadata = {{"pitmap_dod",
                     "B minus A after co-registration (m); lod95: level of detection at 95 %; "
                     "significance -1 loss, 0 no detectable change, +1 gain; region: "
                     "change_regions.geojson id"},
                    {"pitmap_a", a.dir},
                    {"pitmap_b", b.dir}};
    if (auto s = io::WriteCogGeoTiff((C / "dod.tif").string(), dod); !s)
        return Error{"compare: " + s.error().message};
    return Ok{};
}

// A GeoJSON FeatureCollection in the products' UTM CRS (named, as GDAL and QGIS read it).
Status WriteFeatureCollection(const fs::path& path, int epsg, json features) {
    const json fc = {
        {"type", "FeatureCollection"},
        {"crs",
         {{"type", "name"},
          {"properties", {{"name", "urn:ogc:def:crs:EPSG::" + std::to_string(epsg)}}}}},
        {"features", std::move(features)}};
    if (auto s = WriteText(path.string(), fc.dump(1) + "\n"); !s)
        return Error{"compare: " + s.error().message};
    return Ok{};
}

// change_regions.geojson; returns the regions' records for compare.json.
Expected<json> WriteChangeRegions(const fs::path& C,
                                  int epsg,
                                  const compare::ChangeResult& change) {
    json features = json::array();
    json regions = json::array();
    for (const auto& r : change.regions) {
        json polys = json::array();
        for (const auto& poly : r.polygons) {
            json rings = json::array();
            for (const auto& ring : poly) rings.push_back(RingJson(ring));
            polys.push_back(rings);
        }
        const json props = {{"id", r.id},
                            {"kind", r.sign > 0 ? "fill" : "cut"},
                            {"area_m2", r.area_m2},
                            {"volume_m3", r.volume_m3},
                            {"u95_m3", r.u95_m3},
                            {"max_abs_difference_m", r.max_abs_difference_m},
                            {"mean_lod95_m", r.mean_lod95_m}};
        features.push_back({{"type", "Feature"},
                            {"geometry", {{"type", "MultiPolygon"}, {"coordinates", polys}}},
                            {"properties", props}});
        json rj = props;
        rj["centroid_m"] = {r.centroid.x(), r.centroid.y()};
        rj["nodes"] = r.nodes;
        rj["sigma_random_m3"] = r.sigma_random_m3;
        rj["sigma_registration_m3"] = r.sigma_registration_m3;
        rj["rim_m3"] = r.rim_m3;
        rj["mean_difference_m"] = r.mean_difference_m;
        rj["region_lod95_m"] = r.region_lod95_m;
        regions.push_back(rj);
    }
    if (auto s = WriteFeatureCollection(C / "change_regions.geojson", epsg, std::move(features));
        !s)
        return s.error();
    return regions;
}

// The convex hull of points in the plane (Andrew's monotone chain), closed, counter-clockwise.
std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d> p) {
    std::sort(p.begin(), p.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
        return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
    });
    if (p.size() < 3) return p;
    const auto cross =
        [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
            return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
        };
    std::vector<Eigen::Vector2d> h(2 * p.size());
    std::size_t k = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
        while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
        h[k++] = p[i];
    }
    for (std::size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
        while (k >= t && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
        h[k++] = p[i];
    }
    h.resize(k);  // the last equals the first: closed
    return h;
}

// The change mesh's regions of one sign in total, as the 2.5D totals: random, ground offset and
// margin terms in quadrature, registration (one correction) and rims linearly.
struct Totals3d {
    int count = 0;
    double volume_m3 = 0, area_m2 = 0, u95_m3 = 0;
};

Totals3d RegionTotals3d(const compare::ChangeMeshResult& r, int sign, double z95) {
    Totals3d t;
    double var_rand = 0, reg = 0, rim = 0;
    for (const auto& g : r.regions) {
        if (g.sign != sign) continue;
        ++t.count;
        t.volume_m3 += g.volume_m3;
        t.area_m2 += g.area_m2;
        var_rand += g.sigma_random_m3 * g.sigma_random_m3 +
                    g.sigma_ground_offset_m3 * g.sigma_ground_offset_m3 +
                    g.sigma_margin_m3 * g.sigma_margin_m3;
        reg += g.sigma_registration_m3;
        rim += g.rim_m3;
    }
    t.u95_m3 = z95 * std::hypot(std::sqrt(var_rand), reg) + rim;
    return t;
}

// change_regions_3d.geojson (the change mesh's regions: on the surface, walls included; the
// footprint is the convex hull of the region's vertices in plan); returns compare.json's
// change_mesh.regions and the totals.
Expected<json> WriteChangeRegions3d(const fs::path& C,
                                    int epsg,
                                    const compare::TriangleMesh& b,
                                    const compare::ChangeMeshResult& r,
                                    double z95) {
    json features = json::array(), regions = json::array();
    std::vector<std::vector<Eigen::Vector2d>> pts(r.regions.size());
    for (std::size_t i = 0; i < r.region.size(); ++i) {
        if (r.region[i] > 0)
            pts[static_cast<std::size_t>(r.region[i] - 1)].push_back(b.vertices[i].head<2>());
    }
    for (const auto& g : r.regions) {
        const json props = {{"id", g.id},
                            {"kind", g.sign > 0 ? "fill" : "cut"},
                            {"area_m2", g.area_m2},
                            {"volume_m3", g.volume_m3},
                            {"u95_m3", g.u95_m3},
                            {"mean_distance_m", g.mean_distance_m},
                            {"max_abs_distance_m", g.max_abs_distance_m},
                            {"mean_lod95_m", g.mean_lod95_m},
                            {"mean_slope_deg", g.mean_slope_deg},
                            {"z_min_m", g.min.z()},
                            {"z_max_m", g.max.z()}};
        features.push_back({{"type", "Feature"},
                            {"geometry",
                             {{"type", "Polygon"},
                              {"coordinates", json::array({RingJson(ConvexHull(pts[g.id - 1]))})}}},
                            {"properties", props}});
        json rj = props;
        rj["centroid_m"] = {g.centroid.x(), g.centroid.y(), g.centroid.z()};
        rj["axis"] = {g.direction.x(), g.direction.y(), g.direction.z()};
        rj["vertices"] = g.vertices;
        rj["off_axis_vertices"] = g.off_axis_vertices;
        rj["sigma_random_m3"] = g.sigma_random_m3;
        rj["sigma_registration_m3"] = g.sigma_registration_m3;
        rj["rim_m3"] = g.rim_m3;
        rj["ground_offset_m"] = g.ground_offset_m;
        rj["sigma_ground_offset_m3"] = g.sigma_ground_offset_m3;
        rj["ground_band_vertices"] = g.ground_band_vertices;
        rj["margin_m3"] = g.margin_m3;
        rj["sigma_margin_m3"] = g.sigma_margin_m3;
        regions.push_back(rj);
    }
    if (auto s = WriteFeatureCollection(C / "change_regions_3d.geojson", epsg, std::move(features));
        !s)
        return s.error();
    const Totals3d cut = RegionTotals3d(r, -1, z95), fill = RegionTotals3d(r, 1, z95);
    const auto total = [](const Totals3d& t) {
        return json{{"regions", t.count},
                    {"volume_m3", t.volume_m3},
                    {"area_m2", t.area_m2},
                    {"u95_m3", t.u95_m3}};
    };
    return json{{"regions", regions}, {"cut", total(cut)}, {"fill", total(fill)}};
}

// The two capacity curves: capacity_a.csv, capacity_b.csv, capacity.svg.
Status WriteCapacity(const fs::path& C,
                     const compare::CapacityResult& cap_a,
                     const compare::CapacityResult& cap_b,
                     const std::string& datum) {
    if (auto s = WriteText((C / "capacity_a.csv").string(), CapacityCsv(cap_a)); !s)
        return Error{"compare: " + s.error().message};
    if (auto s = WriteText((C / "capacity_b.csv").string(), CapacityCsv(cap_b)); !s)
        return Error{"compare: " + s.error().message};
    if (auto s = WriteText((C / "capacity.svg").string(), CapacitySvg(cap_a, cap_b, datum)); !s)
        return Error{"compare: " + s.error().message};
    return Ok{};
}

json RegistrationJson(const compare::RegistrationResult& reg,
                      const CompareConfig& cfg,
                      const json& gate_record) {
    const auto& T = reg.correction;
    return {{"termination", compare::ToString(reg.termination)},
            {"message", reg.message},
            {"pivot_m", {T.pivot.x(), T.pivot.y(), T.pivot.z()}},
            {"translation_m", {T.translation_m.x(), T.translation_m.y(), T.translation_m.z()}},
            {"rotation_deg",
             {{"roll", T.rotation_rad.x() * kRadToDeg},
              {"pitch", T.rotation_rad.y() * kRadToDeg},
              {"yaw", T.rotation_rad.z() * kRadToDeg}}},
            {"sigma",
             {{"roll_deg", reg.sigma(0) * kRadToDeg},
              {"pitch_deg", reg.sigma(1) * kRadToDeg},
              {"yaw_deg", reg.sigma(2) * kRadToDeg},
              {"east_m", reg.sigma(3)},
              {"north_m", reg.sigma(4)},
              {"up_m", reg.sigma(5)}}},
            {"dof", cfg.registration.estimate_roll_pitch ? 6 : 4},
            {"iterations", reg.iterations},
            {"overlap_area_m2", reg.overlap_area_m2},
            {"nodes_used", reg.points_overlap},
            {"nodes_stable", reg.points_stable},
            {"robust_sigma_m", reg.robust_sigma_m},
            {"rms_vertical_before_m", reg.rms_vertical_before_m},
            {"rms_vertical_after_m", reg.rms_vertical_after_m},
            {"rms_normal_after_m", reg.rms_normal_after_m},
            {"rms_vertical_floor_after_m", reg.rms_vertical_floor_after_m},
            {"nodes_stable_floor", reg.points_stable_floor},
            {"min_soundings", reg.min_soundings_applied},
            {"nodes_sparse", reg.points_sparse},
            {"rms_vertical_all_nodes_after_m", reg.rms_vertical_all_nodes_after_m},
            {"rms_normal_all_nodes_after_m", reg.rms_normal_all_nodes_after_m},
            {"nodes_stable_all_nodes", reg.points_stable_all_nodes},
            {"navigation_gate", gate_record}};
}

json ChangeJson(const compare::ChangeResult& change, double resolution_m, const json& regions) {
    const auto totals = [](const compare::ChangeTotals& t) {
        return json{{"volume_m3", t.volume_m3},
                    {"u95_m3", t.u95_m3},
                    {"area_m2", t.area_m2},
                    {"regions", t.regions}};
    };
    return {{"message", change.message},
            {"compared_nodes", change.compared_nodes},
            {"compared_area_m2", change.compared_area_m2},
            {"resolution_m", resolution_m},
            {"median_lod95_m", change.median_lod95_m},
            {"median_lod95_by_slope_m",
             {{"floor_0_20_deg", change.median_lod95_floor_m},
              {"face_20_45_deg", change.median_lod95_face_m},
              {"wall_45_90_deg", change.median_lod95_wall_m}}},
            {"significant_share", change.significant_share},
            {"regions_below_detection", change.regions_below_detection},
            {"area_below_detection_m2", change.area_below_detection_m2},
            {"stable_mean_m", change.stable_mean_m},
            {"stable_rms_m", change.stable_rms_m},
            {"cut", totals(change.cut)},
            {"fill", totals(change.fill)},
            {"net_m3", change.cut.volume_m3 + change.fill.volume_m3},
            {"regions", regions}};
}

json EpochInputJson(const Epoch& e) {
    return {{"folder", fs::weakly_canonical(e.dir).string()},
            {"run_id", e.run_id},
            {"survey_start_utc", e.start_utc}};
}

// The design surface: its heights as a grid, checked against survey e's CRS and datum.
Expected<compare::SurfaceGrid> ReadDesign(const std::string& path, const Epoch& e) {
    const std::string who = "design (" + path + ")";
    if (!fs::exists(path)) return Error{who + ": not there"};
    std::string ext = fs::path(path).extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".ply") {
        // A mesh in the survey's CRS (mesh_utm.ply's convention), as heights on its grid.
        auto m = formats::ply::ReadMesh(path);
        if (!m) return Error{who + ": " + m.error().message};
        for (const std::string& c : m->comments) {
            if (c.rfind("pitmap_crs_epsg ", 0) != 0) continue;
            const int epsg = std::atoi(c.c_str() + 16);
            if (epsg != e.epsg) {
                return Error{who + ": different horizontal CRS: the design is in EPSG " +
                             std::to_string(epsg) + ", the survey in " + e.horizontal_name +
                             " (EPSG " + std::to_string(e.epsg) + ")"};
            }
        }
        if (m->triangles.empty()) return Error{who + ": a mesh without triangles"};
        compare::TriangleMesh mesh;
        mesh.vertices = std::move(m->vertices);
        mesh.triangles = std::move(m->triangles);
        return compare::RasterizeMesh(mesh, e.surface);
    }
    auto d = io::ReadGrid(path);
    if (!d) return Error{who + ": " + d.error().message};
    if (d->grid.layers.empty()) return Error{who + ": no band"};
    if (d->horizontal_epsg == 0) return Error{who + ": no EPSG-coded horizontal CRS"};
    if (d->horizontal_epsg != e.epsg) {
        return Error{who + ": different horizontal CRS: the design is in " + d->horizontal_name +
                     " (EPSG " + std::to_string(d->horizontal_epsg) + "), the survey " +
                     e.horizontal_name + " (EPSG " + std::to_string(e.epsg) + ")"};
    }
    if (!d->vertical_name.empty() && !e.vertical_name.empty() &&
        d->vertical_name != e.vertical_name) {
        return Error{who + ": different vertical datums: the design's heights are " +
                     d->vertical_name + ", the survey's " + e.vertical_name};
    }
    const io::GridLayer* band = &d->grid.layers.front();
    for (const auto& l : d->grid.layers) {
        if (l.name == "elevation") band = &l;
    }
    compare::SurfaceGrid g;
    g.x0 = d->grid.x0;
    g.y0 = d->grid.y0;
    g.resolution_m = d->grid.resolution_m;
    g.nx = d->grid.nx;
    g.ny = d->grid.ny;
    g.z_m = band->values;
    g.sigma_m.assign(g.z_m.size(), 0.0f);
    if (g.CountFilled() == 0) return Error{who + ": holds no heights"};
    return g;
}

json DesignJson(const compare::DesignResult& d, const std::string& file) {
    return {{"file", file},
            {"message", d.message},
            {"compared_nodes", d.compared_nodes},
            {"compared_area_m2", d.compared_area_m2},
            {"above_design_m3", d.above_m3},
            {"above_design_u95_m3", d.above_u95_m3},
            {"above_design_area_m2", d.above_area_m2},
            {"below_design_m3", d.below_m3},
            {"below_design_u95_m3", d.below_u95_m3},
            {"below_design_area_m2", d.below_area_m2},
            {"significant_above_area_m2", d.significant_above_area_m2},
            {"significant_below_area_m2", d.significant_below_area_m2},
            {"significant_above_m3", d.significant_above_m3},
            {"significant_above_u95_m3", d.significant_above_u95_m3},
            {"significant_below_m3", d.significant_below_m3},
            {"significant_below_u95_m3", d.significant_below_u95_m3},
            {"mean_difference_m", d.mean_difference_m}};
}

// design_a.tif / design_b.tif: the survey against the design on the survey's grid.
Status WriteDesignTif(const fs::path& path, const Epoch& e, const compare::DesignResult& d) {
    io::GridRaster g;
    g.x0 = e.surface.x0;
    g.y0 = e.surface.y0;
    g.resolution_m = e.surface.resolution_m;
    g.nx = e.surface.nx;
    g.ny = e.surface.ny;
    g.utm_zone = e.epsg % 100;
    g.northern = e.epsg < 32700;
    if (!((e.epsg > 32600 && e.epsg <= 32660) || (e.epsg > 32700 && e.epsg <= 32760)))
        return Error{"compare: " + path.string() + ": the CRS is not WGS 84 / UTM"};
    g.horizontal_only = true;
    using K = io::GridBandKind;
    g.layers = {{"difference", "metre", d.difference_m, K::kContinuous},
                {"u95", "metre", d.u95_m, K::kContinuous},
                {"significance", "class", d.significance, K::kCount}};
    g.metadata = {{"pitmap_design",
                   "survey minus design (m); u95: the survey's 95 % uncertainty; significance +1 "
                   "above the design, -1 below, 0 on it"},
                  {"pitmap_survey", e.dir}};
    if (auto s = io::WriteCogGeoTiff(path.string(), g); !s)
        return Error{"compare: " + s.error().message};
    return Ok{};
}

// Each survey against the design (empty when none is given).
struct DesignComparison {
    json record;                                                         // compare.json design
    std::vector<std::pair<std::string, compare::DesignResult>> results;  // file name, result
};

Expected<DesignComparison> CompareDesign(const std::vector<const Epoch*>& epochs,
                                         const CompareConfig& cfg,
                                         const std::function<void(const std::string&)>& log) {
    DesignComparison out;
    if (cfg.design_path.empty()) return out;
    out.record = {{"design", fs::weakly_canonical(cfg.design_path).string()}};
    const char* names[2] = {"a", "b"};
    for (std::size_t k = 0; k < epochs.size(); ++k) {
        auto design = ReadDesign(cfg.design_path, *epochs[k]);
        if (!design) return Error{"compare: " + design.error().message};
        compare::DesignResult d =
            compare::CompareWithDesign(epochs[k]->surface, *design, cfg.design);
        if (d.compared_nodes == 0) {
            return Error{"compare: design (" + cfg.design_path + ") and survey " +
                         (k == 0 ? "A" : "B") + " (" + epochs[k]->dir + ") do not overlap"};
        }
        log(std::string("compare: ") + (k == 0 ? "A" : "B") + " against the design: " + d.message);
        const std::string file = std::string("design_") + names[k] + ".tif";
        out.record[names[k]] = DesignJson(d, file);
        out.results.emplace_back(file, std::move(d));
    }
    return out;
}

// What the comparison found, for compare.json and the log.
struct Comparison {
    compare::RegistrationResult reg;
    compare::ChangeResult change;
    compare::CapacityResult cap_a, cap_b;
    Change3d change3d;
    ChangeOnMesh change_mesh;
    json resolution_match;
    DesignComparison design;
    NavigationGate gate;
    Laps laps;
};

json CompareJson(const Epoch& a,
                 const Epoch& b,
                 const Comparison& r,
                 const CompareConfig& cfg,
                 const json& regions) {
    json j = {
        {"inputs", {{"a", EpochInputJson(a)}, {"b", EpochInputJson(b)}}},
        {"crs",
         {{"horizontal", a.horizontal_name}, {"epsg", a.epsg}, {"vertical", a.vertical_datum_key}}},
        {"registration", RegistrationJson(r.reg, cfg, r.gate.record)},
        {"change", ChangeJson(r.change, a.surface.resolution_m, regions)},
        {"resolution_match", r.resolution_match},
        {"change3d", r.change3d.record},
        {"change_mesh", r.change_mesh.record},
        {"capacity", {{"a", CapacityJson(r.cap_a)}, {"b", CapacityJson(r.cap_b)}}},
        {"files",
         {"dod.tif",
          "change_regions.geojson",
          "capacity_a.csv",
          "capacity_b.csv",
          "capacity.svg",
          "compare.json"}},
        {"quality_gates", r.gate.gates},
        {"cost", r.laps.Record()}};
    if (r.change3d.m3c2) j["files"].push_back("change_points.ply");
    if (r.change_mesh.change) {
        j["files"].push_back("change_mesh.ply");
        j["files"].push_back("change_mesh.glb");
    }
    if (!r.design.results.empty()) {
        j["design"] = r.design.record;
        for (const auto& [file, d] : r.design.results) j["files"].push_back(file);
    }
    return j;
}

// All of C's products.
Status WriteProducts(const std::string& out_dir,
                     const Epoch& a,
                     const Epoch& b,
                     Comparison& r,
                     const CompareConfig& cfg) {
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec) return Error{"compare: " + out_dir + ": cannot create: " + ec.message()};
    const fs::path C(out_dir);
    if (auto s = WriteDod(C, a, b, r.change); !s) return s;
    auto regions = WriteChangeRegions(C, a.epsg, r.change);
    if (!regions) return regions.error();
    if (r.change3d.m3c2) {
        if (auto s = WriteChangePoints(
                (C / "change_points.ply").string(), *r.change3d.m3c2, a.epsg, a.horizontal_name);
            !s)
            return Error{"compare: " + s.error().message};
    }
    json regions3d;
    if (r.change_mesh.change) {
        auto written =
            WriteChangeRegions3d(C, a.epsg, *r.change_mesh.b, *r.change_mesh.change, cfg.mesh.z95);
        if (!written) return written.error();
        regions3d = std::move(*written);
        if (auto s = WriteChangeMesh(out_dir,
                                     *r.change_mesh.b,
                                     *r.change_mesh.change,
                                     a.epsg,
                                     a.horizontal_name,
                                     cfg.change_mesh_colour_scale_m);
            !s)
            return s;
    }
    if (auto s = WriteCapacity(C, r.cap_a, r.cap_b, a.vertical_datum_key); !s) return s;
    for (std::size_t k = 0; k < r.design.results.size(); ++k) {
        const auto& [file, d] = r.design.results[k];
        if (auto s = WriteDesignTif(C / file, k == 0 ? a : b, d); !s) return s;
    }
    r.laps.Lap("write");  // the products but compare.json
    json j = CompareJson(a, b, r, cfg, *regions);
    if (r.change_mesh.change) {
        for (const char* k : {"regions", "cut", "fill"}) j["change_mesh"][k] = regions3d[k];
        j["files"].push_back("change_regions_3d.geojson");
    }
    if (auto s = WriteText((C / "compare.json").string(), j.dump(2) + "\n"); !s)
        return Error{"compare: " + s.error().message};
    return Ok{};
}

std::string SummaryLine(const Comparison& r, const CompareConfig& cfg, const std::string& out_dir) {
    std::string surface;
    if (r.change_mesh.change) {
        const Totals3d cut = RegionTotals3d(*r.change_mesh.change, -1, cfg.mesh.z95);
        const Totals3d fill = RegionTotals3d(*r.change_mesh.change, 1, cfg.mesh.z95);
        char b3[200];
        std::snprintf(b3,
                      sizeof b3,
                      "; on the surface (walls included): cut %.2f +- %.2f m3 in %d regions, "
                      "fill %.2f +- %.2f m3 in %d",
                      cut.volume_m3,
                      cut.u95_m3,
                      cut.count,
                      fill.volume_m3,
                      fill.u95_m3,
                      fill.count);
        surface = b3;
    }
    char buf[256];
    std::snprintf(buf,
                  sizeof buf,
                  "compare: cut %.2f +- %.2f m3, fill %.2f +- %.2f m3 in %zu regions",
                  r.change.cut.volume_m3,
                  r.change.cut.u95_m3,
                  r.change.fill.volume_m3,
                  r.change.fill.u95_m3,
                  r.change.regions.size());
    char cap[120];
    std::snprintf(cap,
                  sizeof cap,
                  "; capacity A %.0f m3, B %.0f m3; products in ",
                  r.cap_a.volume_at_water_level_m3,
                  r.cap_b.volume_at_water_level_m3);
    return buf + surface + cap + out_dir;
}

// Survey A against the design alone.
Expected<int> RunDesignOnly(const std::string& a_dir,
                            const std::string& out_dir,
                            const CompareConfig& cfg,
                            const std::function<void(const std::string&)>& log) {
    if (cfg.design_path.empty())
        return Error{"compare: two products folders, or one and a design surface (--design)"};
    auto a = ReadEpoch(a_dir, "A");
    if (!a) return Error{"compare: " + a.error().message};
    auto design = CompareDesign({&*a}, cfg, log);
    if (!design) return design.error();
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec) return Error{"compare: " + out_dir + ": cannot create: " + ec.message()};
    const auto& [file, d] = design->results.front();
    if (auto s = WriteDesignTif(fs::path(out_dir) / file, *a, d); !s) return s.error();
    const json j = {{"inputs", {{"a", EpochInputJson(*a)}}},
                    {"crs",
                     {{"horizontal", a->horizontal_name},
                      {"epsg", a->epsg},
                      {"vertical", a->vertical_datum_key}}},
                    {"design", design->record},
                    {"files", {file, "compare.json"}},
                    {"quality_gates", json::array()}};
    if (auto s = WriteText((fs::path(out_dir) / "compare.json").string(), j.dump(2) + "\n"); !s)
        return Error{"compare: " + s.error().message};
    log("compare: products in " + out_dir);
    return 0;
}

}  // namespace

std::vector<std::string> CompareConfig::Validate() const {
    std::vector<std::string> p = registration.Validate();
    for (auto& q : change.Validate()) p.push_back(std::move(q));
    for (auto& q : m3c2.Validate()) p.push_back(std::move(q));
    for (auto& q : mesh.Validate()) p.push_back(std::move(q));
    for (auto& q : design.Validate()) p.push_back(std::move(q));
    if (!(change_mesh_colour_scale_m > 0)) p.push_back("change mesh colour scale must be > 0");
    if (!(capacity_step_m > 0 && capacity_step_m <= 100))
        p.push_back("capacity step must be in (0, 100] m");
    if (!(gate_z95 > 0)) p.push_back("gate_z95 must be > 0");
    return p;
}

Expected<int> RunCompare(const std::string& a_dir,
                         const std::string& b_dir,
                         const std::string& out_dir,
                         const CompareConfig& cfg,
                         const std::function<void(const std::string&)>& log) {
    if (auto problems = cfg.Validate(); !problems.empty())
        return Error{"compare: invalid settings: " + problems.front()};
    if (b_dir.empty()) return RunDesignOnly(a_dir, out_dir, cfg, log);
    if (fs::weakly_canonical(a_dir) == fs::weakly_canonical(b_dir))
        return Error{"compare: A and B are the same folder (" + a_dir + ")"};
    Comparison r;  // its clock starts here
    auto a = ReadEpochProducts(a_dir, "A");
    if (!a) return Error{"compare: " + a.error().message};
    auto b = ReadEpochProducts(b_dir, "B");
    if (!b) return Error{"compare: " + b.error().message};
    // The survey models, whole: the one gridded again is loaded by its regrid.
    const compare::CommonGridPlan plan =
        compare::PlanCommonGrid(a->surface.resolution_m, b->surface.resolution_m);
    for (Epoch* e : {&*a, &*b}) {
        const bool regridded = (e == &*a && plan.regrid == compare::Regridded::kA) ||
                               (e == &*b && plan.regrid == compare::Regridded::kB);
        if (regridded) continue;
        if (auto st = CheckSurvey(*e); !st) return Error{"compare: " + st.error().message};
    }
    if (auto s = CheckComparable(*a, *b, log); !s) return s.error();

    r.laps.Lap("read");
    // The capacity curves on each survey's surface as it is.
    r.cap_a = compare::ComputeCapacity(a->surface, a->water_level_m, cfg.capacity_step_m);
    r.cap_b = compare::ComputeCapacity(b->surface, b->water_level_m, cfg.capacity_step_m);
    auto design = CompareDesign({&*a, &*b}, cfg, log);
    if (!design) return design.error();
    r.design = std::move(*design);
    r.laps.Lap("capacity_design");
    // One resolution for the registration and the DEM of difference (decision 030).
    json regrid_record;
    const auto regrid_of = [&](Epoch& e) -> compare::RegridSurvey {
        return [&e, &cfg, &log, &regrid_record](double res) {
            return RegridEpoch(e, res, cfg.survey, log, regrid_record);
        };
    };
    auto common = compare::OnCommonGrid(a->surface, b->surface, regrid_of(*a), regrid_of(*b));
    if (!common) return Error{"compare: " + common.error().message};
    r.resolution_match = {{"a_resolution_m", a->surface.resolution_m},
                          {"b_resolution_m", b->surface.resolution_m},
                          {"common_resolution_m", common->plan.resolution_m},
                          {"regridded", compare::ToString(common->plan.regrid)}};
    if (common->plan.regrid != compare::Regridded::kNone)
        r.resolution_match["regrid"] = regrid_record;
    a->surface = std::move(common->a);
    b->surface = std::move(common->b);
    r.laps.Lap("regrid");
    log("compare: registering B onto A on stable terrain");
    r.reg = compare::RegisterSurfaces(a->surface, b->surface, cfg.registration);
    if (!r.reg.ok()) {
        return Error{"compare: registration failed: " + r.reg.message +
                     (r.reg.termination == compare::RegistrationTermination::kTooFewPoints
                          ? " (the surveys do not overlap enough)"
                          : "")};
    }
    log("compare: registration " + r.reg.message);
    r.laps.Lap("registration");
    r.change = compare::ComputeChange(
        a->surface, b->surface, r.reg.correction, r.reg.covariance, cfg.change);
    log("compare: change: " + r.change.message);
    r.laps.Lap("dod");
    auto change3d = ComputeChange3d(*a, *b, r.reg, cfg, log);
    if (!change3d) return change3d.error();
    r.change3d = std::move(*change3d);
    r.laps.Lap("change3d");
    auto on_mesh = ComputeChangeOnMesh(*a, *b, r.reg, r.change3d, cfg, log);
    if (!on_mesh) return on_mesh.error();
    r.change_mesh = std::move(*on_mesh);
    ConfirmMeshRegions(r.change3d, cfg, log, r.change_mesh);
    r.gate = CheckNavigation(*a, *b, r.reg, cfg);
    r.laps.Lap("change_mesh");

    if (auto s = WriteProducts(out_dir, *a, *b, r, cfg); !s) return s.error();
    log(SummaryLine(r, cfg, out_dir));
    return static_cast<int>(r.gate.gates.size());
}

Expected<json> SurveyCapacity(const std::string& dir, const json& summary, double step_m) {
    if (!(step_m > 0)) return Error{"capacity: the step must be > 0"};
    auto dem = io::ReadGrid((fs::path(dir) / "dem.tif").string());
    if (!dem) return dem.error();
    compare::SurfaceGrid g;
    g.x0 = dem->grid.x0;
    g.y0 = dem->grid.y0;
    g.resolution_m = dem->grid.resolution_m;
    g.nx = dem->grid.nx;
    g.ny = dem->grid.ny;
    for (const auto& l : dem->grid.layers) {
        if (l.name == "elevation") g.z_m = l.values;
    }
    if (g.z_m.empty()) return Error{"dem.tif has no elevation band"};
    g.sigma_m.assign(g.z_m.size(), 0.0f);
    if (g.CountFilled() == 0) return Error{"dem.tif holds no heights"};
    double datum_h = 0;
    if (summary.contains("vertical_datum") && summary["vertical_datum"].is_object()) {
        const json& v = summary["vertical_datum"];
        if (v.value("datum", std::string("ellipsoid")) != "ellipsoid") {
            const json& h = v.value("mean_datum_height_m", json());
            datum_h = h.is_number() ? h.get<double>() : 0.0;
        }
    }
    auto level = WaterLevelOf(dir, summary, datum_h);
    if (!level) return level.error();
    const compare::CapacityResult c = compare::ComputeCapacity(g, *level, step_m);
    if (auto st = WriteText((fs::path(dir) / "capacity.csv").string(), CapacityCsv(c)); !st)
        return st.error();
    json j = CapacityJson(c);
    j["step_m"] = step_m;
    j["file"] = "capacity.csv";
    json rows = json::array();
    for (const auto& r : c.rows) {
        // Unrounded: the last row's level is the water level itself (a depth of 0).
        rows.push_back({r.level_m, r.area_m2, r.volume_m3});
    }
    j["rows_level_area_volume"] = std::move(rows);
    return j;
}

Status WriteCompareReport(const std::string& out_dir,
                          const std::string& report_program,
                          const std::function<void(const std::string&)>& log) {
    auto run = RunReportProgram(report_program,
                                {"--compare", out_dir},
                                "the comparison is complete without report.html (pitmap "
                                "compare --no-report skips it)");
    if (!run) return run.error();
    char buf[160];
    std::snprintf(
        buf, sizeof buf, " (%.1f s of CPU, peak %.0f MB)", run->cpu_seconds, run->peak_rss_mb);
    log("compare: change report " + (fs::path(out_dir) / "report.html").string() + buf);
    return Ok{};
}

namespace {

// A folder of the series: its name, survey start and CRS, read from summary.json.
struct SeriesEntry {
    std::string dir, name, start_utc;
    int epsg = 0;
};

Expected<std::vector<std::string>> ExpandSeriesList(const std::vector<std::string>& dirs) {
    if (dirs.size() != 1 || fs::is_directory(dirs.front())) return dirs;
    std::ifstream in(dirs.front());
    if (!in) return Error{"compare: " + dirs.front() + ": cannot read the list of folders"};
    std::vector<std::string> out;
    const fs::path base = fs::path(dirs.front()).parent_path();
    for (std::string line; std::getline(in, line);) {
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
        const auto first = line.find_first_not_of(' ');
        if (first == std::string::npos || line[first] == '#') continue;
        const fs::path p(line.substr(first));
        out.push_back((p.is_absolute() ? p : base / p).string());
    }
    if (out.size() < 2)
        return Error{"compare: " + dirs.front() + ": lists " + std::to_string(out.size()) +
                     " folder(s); a series needs at least two"};
    return out;
}

Expected<SeriesEntry> ReadSeriesEntry(const std::string& dir) {
    SeriesEntry e;
    e.dir = dir;
    e.name = fs::path(dir).lexically_normal().filename().string();
    if (e.name.empty() || e.name == ".") e.name = fs::weakly_canonical(dir).filename().string();
    if (!fs::is_directory(dir)) return Error{"compare: " + dir + ": not a products folder"};
    auto s = io::ReadSummaryJson((fs::path(dir) / "summary.json").string());
    if (!s) return Error{"compare: " + dir + ": " + s.error().message};
    if (s->contains("metadata") && (*s)["metadata"].is_object())
        e.start_utc = (*s)["metadata"].value("survey_start_utc", std::string());
    if (e.start_utc.empty())
        return Error{"compare: " + dir +
                     ": summary.json names no survey_start_utc (metadata): the series' order "
                     "cannot be checked"};
    if (s->contains("utm") && (*s)["utm"].is_object()) e.epsg = (*s)["utm"].value("epsg", 0);
    if (e.epsg == 0) return Error{"compare: " + dir + ": summary.json names no utm.epsg"};
    return e;
}

}  // namespace

Expected<int> RunCompareSeries(const std::vector<std::string>& dirs_in,
                               const std::string& out_dir,
                               const CompareConfig& cfg,
                               const std::function<void(const std::string&)>& log) {
    auto dirs = ExpandSeriesList(dirs_in);
    if (!dirs) return dirs.error();
    if (dirs->size() < 2) return Error{"compare: a series needs at least two products folders"};
    std::vector<SeriesEntry> entries;
    for (const std::string& d : *dirs) {
        auto e = ReadSeriesEntry(d);
        if (!e) return e.error();
        if (!entries.empty()) {
            const SeriesEntry& prev = entries.back();
            // ISO 8601 UTC stamps of one form order as text.
            if (!(e->start_utc > prev.start_utc)) {
                return Error{"compare: " + d + " is out of time order: surveyed " + e->start_utc +
                             ", not after " + prev.dir + " (" + prev.start_utc +
                             "); give the folders earliest first"};
            }
            if (e->epsg != entries.front().epsg) {
                return Error{"compare: " + d + " is in another CRS (EPSG " +
                             std::to_string(e->epsg) + ") than " + entries.front().dir + " (EPSG " +
                             std::to_string(entries.front().epsg) + ")"};
            }
        }
        entries.push_back(std::move(*e));
    }
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec) return Error{"compare: " + out_dir + ": cannot create: " + ec.message()};
    json intervals = json::array();
    std::string csv =
        "interval,from,to,from_utc,to_utc,cut_m3,cut_u95_m3,fill_m3,fill_u95_m3,net_m3,"
        "net_u95_m3,cumulative_net_m3,cumulative_net_u95_m3,gates\n";
    double cumulative = 0, cumulative_var = 0;
    int gates = 0;
    for (std::size_t k = 0; k + 1 < entries.size(); ++k) {
        const SeriesEntry& a = entries[k];
        const SeriesEntry& b = entries[k + 1];
        char sub[32];
        std::snprintf(sub, sizeof sub, "%02zu_", k + 1);
        const std::string folder = sub + a.name + "_to_" + b.name;
        log("compare: interval " + std::to_string(k + 1) + ": " + a.dir + " -> " + b.dir);
        auto g = RunCompare(a.dir, b.dir, (fs::path(out_dir) / folder).string(), cfg, log);
        if (!g) return Error{g.error().message + " (interval " + std::to_string(k + 1) + ")"};
        gates += *g;
        auto cj = io::ReadJsonFile((fs::path(out_dir) / folder / "compare.json").string());
        if (!cj) return Error{"compare: " + cj.error().message};
        const json& c = *cj;
        const json& ch = c["change"];
        const double cut = ch["cut"]["volume_m3"], cut_u = ch["cut"]["u95_m3"];
        const double fill = ch["fill"]["volume_m3"], fill_u = ch["fill"]["u95_m3"];
        const double net = cut + fill, net_u = std::hypot(cut_u, fill_u);
        cumulative += net;
        cumulative_var += net_u * net_u;
        const double cumulative_u = std::sqrt(cumulative_var);
        intervals.push_back({{"interval", k + 1},
                             {"folder", folder},
                             {"from", {{"folder", a.dir}, {"survey_start_utc", a.start_utc}}},
                             {"to", {{"folder", b.dir}, {"survey_start_utc", b.start_utc}}},
                             {"cut_m3", cut},
                             {"cut_u95_m3", cut_u},
                             {"fill_m3", fill},
                             {"fill_u95_m3", fill_u},
                             {"net_m3", net},
                             {"net_u95_m3", net_u},
                             {"cumulative_net_m3", cumulative},
                             {"cumulative_net_u95_m3", cumulative_u},
                             {"quality_gates", c["quality_gates"]}});
        char line[512];
        std::snprintf(line,
                      sizeof line,
                      "%zu,%s,%s,%s,%s,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d\n",
                      k + 1,
                      a.name.c_str(),
                      b.name.c_str(),
                      a.start_utc.c_str(),
                      b.start_utc.c_str(),
                      cut,
                      cut_u,
                      fill,
                      fill_u,
                      net,
                      net_u,
                      cumulative,
                      cumulative_u,
                      *g);
        csv += line;
    }
    json surveys = json::array();
    for (const SeriesEntry& e : entries)
        surveys.push_back(
            {{"folder", fs::weakly_canonical(e.dir).string()}, {"survey_start_utc", e.start_utc}});
    const json series = {{"surveys", surveys},
                         {"epsg", entries.front().epsg},
                         {"intervals", intervals},
                         {"cumulative_net_m3", cumulative},
                         {"cumulative_net_u95_m3", std::sqrt(cumulative_var)},
                         {"quality_gates_tripped", gates}};
    if (auto s = WriteText((fs::path(out_dir) / "series.csv").string(), csv); !s)
        return Error{"compare: " + s.error().message};
    if (auto s = WriteText((fs::path(out_dir) / "series.json").string(), series.dump(2) + "\n"); !s)
        return Error{"compare: " + s.error().message};
    log("compare: series of " + std::to_string(entries.size()) + " surveys, " +
        std::to_string(entries.size() - 1) + " intervals in " + out_dir);
    return gates;
}

}  // namespace pitmap::proc::pipeline
