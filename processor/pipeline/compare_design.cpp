// SPDX-License-Identifier: MIT
#include <cctype>
#include <cstdlib>
#include <filesystem>

#include "common/formats/ply.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/pipeline/compare_internal.hpp"

namespace pitmap::proc::pipeline::compare_detail {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

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

}  // namespace

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

}  // namespace pitmap::proc::pipeline::compare_detail
