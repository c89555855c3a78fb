// SPDX-License-Identifier: MIT
#include <cmath>
#include <filesystem>

#include "common/formats/ply.hpp"
#include "processor/pipeline/compare_internal.hpp"
#include "processor/pipeline/compare_stage_mesh.hpp"

namespace pitmap::proc::pipeline::compare_detail {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

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

}  // namespace

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

}  // namespace pitmap::proc::pipeline::compare_detail
