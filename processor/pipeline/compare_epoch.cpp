// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/formats/trajectory_csv.hpp"
#include "processor/hydro/cube.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/io/products.hpp"
#include "processor/pipeline/compare_internal.hpp"
#include "processor/pipeline/internal.hpp"
#include "processor/survey/survey_file.hpp"

namespace pitmap::proc::pipeline::compare_detail {

namespace fs = std::filesystem;
using nlohmann::json;
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

namespace {

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

json NavSigmaJson(const NavSigma& n) {
    return {{"horizontal_m", n.horizontal_m},
            {"vertical_m", n.vertical_m},
            {"roll_pitch_deg", n.roll_pitch_deg},
            {"yaw_deg", n.yaw_deg}};
}

}  // namespace

double Median(std::vector<double> v) {
    if (v.empty()) return std::nan("");
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
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

json EpochInputJson(const Epoch& e) {
    return {{"folder", fs::weakly_canonical(e.dir).string()},
            {"run_id", e.run_id},
            {"survey_start_utc", e.start_utc}};
}

}  // namespace pitmap::proc::pipeline::compare_detail
