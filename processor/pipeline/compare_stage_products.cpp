// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "common/byte_io.hpp"
#include "common/formats/ply.hpp"
#include "common/formats/replace_file.hpp"
#include "processor/io/grid_io.hpp"
#include "processor/pipeline/compare_internal.hpp"

namespace pitmap::proc::pipeline::compare_detail {

namespace fs = std::filesystem;
using nlohmann::json;
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

namespace {

json RingJson(const std::vector<Eigen::Vector2d>& ring) {
    json r = json::array();
    for (const auto& p : ring) {
        r.push_back({std::round(p.x() * 1000.0) / 1000.0, std::round(p.y() * 1000.0) / 1000.0});
    }
    return r;
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

}  // namespace

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

}  // namespace pitmap::proc::pipeline::compare_detail
