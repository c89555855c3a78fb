// SPDX-License-Identifier: MIT
#include "processor/pipeline/compare_stage.hpp"

#include <time.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "common/peak_memory.hpp"
#include "processor/compare/capacity.hpp"
#include "processor/compare/common_grid.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/io/products.hpp"
#include "processor/pipeline/compare_internal.hpp"
#include "processor/pipeline/compare_stage_mesh.hpp"
#include "processor/pipeline/report_program.hpp"

namespace pitmap::proc::pipeline {
namespace {

namespace fs = std::filesystem;
using compare_detail::CapacityCsv;
using compare_detail::CapacityJson;
using compare_detail::Change3d;
using compare_detail::ChangeJson;
using compare_detail::ChangeOnMesh;
using compare_detail::CheckComparable;
using compare_detail::CheckNavigation;
using compare_detail::CheckSurvey;
using compare_detail::CompareDesign;
using compare_detail::ComputeChange3d;
using compare_detail::ComputeChangeOnMesh;
using compare_detail::ConfirmMeshRegions;
using compare_detail::DesignComparison;
using compare_detail::Epoch;
using compare_detail::EpochInputJson;
using compare_detail::NavigationGate;
using compare_detail::ReadEpochProducts;
using compare_detail::RegionTotals3d;
using compare_detail::RegistrationJson;
using compare_detail::RegridEpoch;
using compare_detail::RunDesignOnly;
using compare_detail::Totals3d;
using compare_detail::WaterLevelOf;
using compare_detail::WriteCapacity;
using compare_detail::WriteChangePoints;
using compare_detail::WriteChangeRegions;
using compare_detail::WriteChangeRegions3d;
using compare_detail::WriteDesignTif;
using compare_detail::WriteDod;
using compare_detail::WriteText;
using nlohmann::json;

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

}  // namespace pitmap::proc::pipeline
