// SPDX-License-Identifier: MIT
#include "processor/compare/change_mesh.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include "processor/registration/neighbours.hpp"

namespace pitmap::proc::compare {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// A's triangles by the voxels their bounding boxes touch: (cell key, triangle) sorted by key.
class TriangleIndex {
public:
    TriangleIndex(const TriangleMesh& m, double cell) : mesh_(m), cell_(cell) {
        origin_ = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
        for (const auto& v : m.vertices) origin_ = origin_.cwiseMin(v);
        for (std::size_t t = 0; t < m.triangles.size(); ++t) {
            Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
            Eigen::Vector3d hi = -lo;
            for (int k : m.triangles[t]) {
                lo = lo.cwiseMin(m.vertices[static_cast<std::size_t>(k)]);
                hi = hi.cwiseMax(m.vertices[static_cast<std::size_t>(k)]);
            }
            const Eigen::Vector3i c0 = Cell(lo), c1 = Cell(hi);
            for (int z = c0.z(); z <= c1.z(); ++z)
                for (int y = c0.y(); y <= c1.y(); ++y)
                    for (int x = c0.x(); x <= c1.x(); ++x)
                        entries_.emplace_back(Key(x, y, z), static_cast<int>(t));
        }
        std::sort(entries_.begin(), entries_.end());
    }
    Eigen::Vector3i Cell(const Eigen::Vector3d& p) const {
        const Eigen::Vector3d q = (p - origin_) / cell_;
        return {static_cast<int>(std::floor(q.x())),
                static_cast<int>(std::floor(q.y())),
                static_cast<int>(std::floor(q.z()))};
    }
    static std::uint64_t Key(int x, int y, int z) {
        const auto u = [](int v) { return static_cast<std::uint64_t>(v + (1 << 20)) & 0x1FFFFF; };
        return (u(x) << 42) | (u(y) << 21) | u(z);
    }
    // The nearest hit (smallest |t|) of p + t n, |t| <= r, with A's triangles; NaN if none.
    double Hit(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double r) const {
        const Eigen::Vector3d s = p - r * n;  // walk from s along n for 2r
        const double len = 2 * r;
        Eigen::Vector3i c = Cell(s);
        const Eigen::Vector3i c_end = Cell(p + r * n);
        Eigen::Vector3i step;
        Eigen::Vector3d t_max, t_delta;
        for (int k = 0; k < 3; ++k) {
            step[k] = n[k] > 0 ? 1 : (n[k] < 0 ? -1 : 0);
            const double inf = std::numeric_limits<double>::infinity();
            if (step[k] == 0) {
                t_max[k] = inf;
                t_delta[k] = inf;
                continue;
            }
            const double edge = origin_[k] + (c[k] + (step[k] > 0 ? 1 : 0)) * cell_;
            t_max[k] = (edge - s[k]) / n[k];
            t_delta[k] = cell_ / std::abs(n[k]);
        }
        double best = std::numeric_limits<double>::quiet_NaN();
        for (int guard = 0; guard < 4096; ++guard) {
            const std::uint64_t key = Key(c.x(), c.y(), c.z());
            auto it = std::lower_bound(entries_.begin(),
                                       entries_.end(),
                                       std::make_pair(key, std::numeric_limits<int>::min()));
            for (; it != entries_.end() && it->first == key; ++it) {
                const double t = Intersect(it->second, s, n);
                if (!std::isfinite(t) || t < 0 || t > len) continue;
                const double along = t - r;
                if (!std::isfinite(best) || std::abs(along) < std::abs(best)) best = along;
            }
            if (c == c_end) break;
            int k = 0;
            if (t_max.y() < t_max[k]) k = 1;
            if (t_max.z() < t_max[k]) k = 2;
            if (t_max[k] > len) break;
            c[k] += step[k];
            t_max[k] += t_delta[k];
        }
        return best;
    }

private:
    // Moller-Trumbore: t along n from s where the line meets triangle `tri`, NaN if it misses.
    double Intersect(int tri, const Eigen::Vector3d& s, const Eigen::Vector3d& n) const {
        const auto& t = mesh_.triangles[static_cast<std::size_t>(tri)];
        const Eigen::Vector3d& v0 = mesh_.vertices[static_cast<std::size_t>(t[0])];
        const Eigen::Vector3d e1 = mesh_.vertices[static_cast<std::size_t>(t[1])] - v0;
        const Eigen::Vector3d e2 = mesh_.vertices[static_cast<std::size_t>(t[2])] - v0;
        const Eigen::Vector3d h = n.cross(e2);
        const double det = e1.dot(h);
        if (std::abs(det) < 1e-14) return std::numeric_limits<double>::quiet_NaN();
        const Eigen::Vector3d q = s - v0;
        const double u = q.dot(h) / det;
        if (u < -1e-9 || u > 1 + 1e-9) return std::numeric_limits<double>::quiet_NaN();
        const Eigen::Vector3d w = q.cross(e1);
        const double v = n.dot(w) / det;
        if (v < -1e-9 || u + v > 1 + 1e-9) return std::numeric_limits<double>::quiet_NaN();
        return e2.dot(w) / det;
    }
    const TriangleMesh& mesh_;
    double cell_;
    Eigen::Vector3d origin_;
    std::vector<std::pair<std::uint64_t, int>> entries_;
};

// Area-weighted vertex normals of `m`; turned over as a whole when they point down on average.
std::vector<Eigen::Vector3f> VertexNormals(const TriangleMesh& m, bool* flipped) {
    std::vector<Eigen::Vector3d> acc(m.vertices.size(), Eigen::Vector3d::Zero());
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (const auto& t : m.triangles) {
        const Eigen::Vector3d& a = m.vertices[static_cast<std::size_t>(t[0])];
        const Eigen::Vector3d fn = (m.vertices[static_cast<std::size_t>(t[1])] - a)
                                       .cross(m.vertices[static_cast<std::size_t>(t[2])] - a);
        for (int k : t) acc[static_cast<std::size_t>(k)] += fn;
        total += fn;
    }
    *flipped = total.z() < 0;
    std::vector<Eigen::Vector3f> out(acc.size(), Eigen::Vector3f::Zero());
    for (std::size_t i = 0; i < acc.size(); ++i) {
        const double len = acc[i].norm();
        if (len > 0) out[i] = ((*flipped ? -1.0 : 1.0) * acc[i] / len).cast<float>();
    }
    return out;
}

// A region's sums while its vertices are walked (Regions).
struct RegionAcc {
    ChangeRegion3d reg;
    Eigen::Vector3d sum_an = Eigen::Vector3d::Zero();
    double sum_sigma2_a = 0, lod_a = 0, slope_a = 0, projected = 0;
    Eigen::Matrix<double, 1, 6> sum_aJ = Eigen::Matrix<double, 1, 6>::Zero();
};

// Each region's ground offset (change_mesh.hpp): the median distance of the measured vertices
// with no detectable change (|d| <= LoD95, in no region) between ground_band_inner_m and
// ground_band_outer_m from the region's nearest vertex, whose normals lie within
// ground_band_max_angle_deg of its axis u; and its 1-sigma times the region's projected area.
// Sets acc[k].reg.ground_offset_m, sigma_ground_offset_m3, ground_band_vertices.
void GroundOffsets(const TriangleMesh& m,
                   const ChangeMeshConfig& cfg,
                   const std::vector<double>& area,
                   const std::vector<Eigen::Vector3d>& u,
                   const ChangeMeshResult& r,
                   std::vector<RegionAcc>& acc) {
    const double outer = cfg.ground_band_outer_m, inner = cfg.ground_band_inner_m;
    if (acc.empty() || !(outer > 0)) return;  // Validate: outer > inner >= 0, margin <= outer
    // The unchanged measured vertices by cells of the band's outer width.
    const auto cell_of = [outer](const Eigen::Vector3d& p) {
        return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / outer)),
                               static_cast<int>(std::floor(p.y() / outer)),
                               static_cast<int>(std::floor(p.z() / outer)));
    };
    const auto key = [](const Eigen::Vector3i& c) {
        const auto f = [](int v) { return static_cast<std::uint64_t>(v + (1 << 20)) & 0x1FFFFF; };
        return (f(c.x()) << 42) | (f(c.y()) << 21) | f(c.z());
    };
    std::unordered_map<std::uint64_t, std::vector<int>> cells;
    std::vector<std::vector<Eigen::Vector3d>> members(acc.size());
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
        if (r.region[i] != 0) {
            members[static_cast<std::size_t>(r.region[i] - 1)].push_back(m.vertices[i]);
            continue;
        }
        const float d = r.distance_m[i];
        if (!std::isfinite(d) || std::abs(d) > r.lod95_m[i]) continue;
        cells[key(cell_of(m.vertices[i]))].push_back(static_cast<int>(i));
    }
    const double min_cos = std::cos(cfg.ground_band_max_angle_deg * 3.14159265358979 / 180.0);
    const double L2 = cfg.error_correlation_length_m * cfg.error_correlation_length_m;
    std::vector<double> band;
    struct MarginVertex {
        double projected_area, distance, sigma;
    };
    std::vector<MarginVertex> margin;
    for (std::size_t k = 0; k < acc.size(); ++k) {
        const reg::PointIndex<double> index(members[k].data(), members[k].size());
        const Eigen::Vector3i c0 = cell_of(acc[k].reg.min) - Eigen::Vector3i::Ones();
        const Eigen::Vector3i c1 = cell_of(acc[k].reg.max) + Eigen::Vector3i::Ones();
        band.clear();
        margin.clear();
        double band_area = 0;
        const double w = cfg.margin_band_m;
        for (int z = c0.z(); z <= c1.z(); ++z) {
            for (int y = c0.y(); y <= c1.y(); ++y) {
                for (int x = c0.x(); x <= c1.x(); ++x) {
                    const auto it = cells.find(key({x, y, z}));
                    if (it == cells.end()) continue;
                    for (int v : it->second) {
                        const auto i = static_cast<std::size_t>(v);
                        std::size_t nearest = 0;
                        double d2 = 0;
                        if (!index.NearestWithin(m.vertices[i], outer * outer, &nearest, &d2))
                            continue;
                        const double cos_u = r.normals[i].cast<double>().dot(u[k]);
                        if (d2 <= w * w) {
                            margin.push_back({area[i] * std::abs(cos_u),
                                              r.distance_m[i],
                                              r.lod95_m[i] / cfg.z95});
                        }
                        if (d2 < inner * inner || cos_u < min_cos) continue;
                        band.push_back(r.distance_m[i]);
                        band_area += area[i];
                    }
                }
            }
        }
        ChangeRegion3d& g = acc[k].reg;
        g.ground_band_vertices = band.size();
        if (band.size() < cfg.ground_band_min_vertices) {
            g.ground_band_vertices = 0;
            band.clear();
        }
        double o = 0;
        if (!band.empty()) {
            const auto mid = band.begin() + static_cast<std::ptrdiff_t>(band.size() / 2);
            std::nth_element(band.begin(), mid, band.end());
            o = *mid;
            for (double& b : band) b = std::abs(b - o);
            std::nth_element(band.begin(), mid, band.end());
            const double s = 1.4826 * *mid;
            g.ground_offset_m = o;
            g.sigma_ground_offset_m3 =
                acc[k].projected * 1.2533 * s /
                std::sqrt(std::max(1.0, L2 > 0 ? band_area / L2 : band_area));
        }
        // The margin: what the band just outside holds above the ground around it.
        double margin_area = 0, margin_var = 0;
        for (const auto& [ap, d, sigma] : margin) {
            g.margin_m3 += ap * (d - o);
            margin_area += ap;
            margin_var += ap * sigma * sigma;
        }
        g.sigma_margin_m3 = std::sqrt(std::min(L2, margin_area) * margin_var);
    }
}

// The kept patches as regions with their volumes and uncertainty (change_mesh.hpp); root(i):
// vertex i's patch; index: A's triangles.
template <typename Root>
void Regions(const TriangleMesh& m,
             const ChangeMeshConfig& cfg,
             const std::vector<double>& area,
             const std::vector<float>& sigma,
             const RigidCorrection& T,
             const Eigen::Matrix<double, 6, 6>& C,
             const TriangleIndex& index,
             Root&& root,
             ChangeMeshResult& r) {
    const std::size_t n = m.vertices.size();
    r.region.assign(n, 0);
    std::vector<RegionAcc> acc;
    std::vector<int> id_of_root(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        if (r.significance[i] == 0) continue;
        const auto rt = static_cast<std::size_t>(root(static_cast<int>(i)));
        if (id_of_root[rt] == 0) {
            acc.emplace_back();
            id_of_root[rt] = static_cast<int>(acc.size());
            acc.back().reg.sign = r.significance[i];
            acc.back().reg.min = acc.back().reg.max = m.vertices[i];
        }
        r.region[i] = id_of_root[rt];
        acc[static_cast<std::size_t>(r.region[i] - 1)].sum_an +=
            area[i] * r.normals[i].cast<double>();
    }
    // Each region's volume along its mean normal u: the prisms a_i (n_i . u) x t_i (t_i from
    // the vertex along u to A's surface) are parallel and do not overlap. Along each vertex's
    // own normal they would: on a heap's flanks the normals converge beneath it, and the sum
    // of a_i d_i exceeds the volume by 1 / cos^2 of the flank's slope to the floor (+11 % on
    // the quarry's 0.6 m heap).
    std::vector<Eigen::Vector3d> u(acc.size());
    for (std::size_t k = 0; k < acc.size(); ++k) u[k] = acc[k].sum_an.normalized();
    for (std::size_t i = 0; i < n; ++i) {
        if (r.region[i] == 0) continue;
        const auto k = static_cast<std::size_t>(r.region[i] - 1);
        RegionAcc& a = acc[k];
        const Eigen::Vector3d& p = m.vertices[i];
        const Eigen::Vector3d nrm = r.normals[i].cast<double>();
        const double d = r.distance_m[i];
        double along = -index.Hit(p, u[k], cfg.max_distance_m);
        double ai = area[i] * std::abs(nrm.dot(u[k]));
        if (!std::isfinite(along)) {
            // A has no surface along u within reach: the vertex's own prism.
            along = d;
            ai = area[i];
            ++a.reg.off_axis_vertices;
        }
        ++a.reg.vertices;
        a.reg.area_m2 += area[i];
        a.projected += ai;
        a.reg.volume_m3 += ai * along;
        a.reg.max_abs_distance_m = std::max(a.reg.max_abs_distance_m, std::abs(d));
        a.reg.centroid += area[i] * p;
        a.reg.min = a.reg.min.cwiseMin(p);
        a.reg.max = a.reg.max.cwiseMax(p);
        a.lod_a += area[i] * r.lod95_m[i];
        a.slope_a +=
            area[i] * std::acos(std::min(1.0, std::abs(nrm.z()))) * 180.0 / 3.14159265358979;
        a.sum_sigma2_a += static_cast<double>(sigma[i]) * sigma[i] * ai;
        Eigen::Matrix<double, 1, 6> J;
        J.head<3>() = ((p - T.pivot).cross(u[k])).transpose();
        J.tail<3>() = u[k].transpose();
        a.sum_aJ += ai * J;
    }
    // The rim: measured vertices outside a region joined to it by an edge (each counted once
    // per region it borders).
    std::vector<int> rim_of(n, 0);
    for (const auto& t : m.triangles) {
        for (int k = 0; k < 3; ++k) {
            for (int e : {1, 2}) {
                const auto v0 = static_cast<std::size_t>(t[k]);
                const auto v = static_cast<std::size_t>(t[(k + e) % 3]);
                if (r.region[v0] == 0 || r.region[v] != 0 || !std::isfinite(r.distance_m[v]))
                    continue;
                if (rim_of[v] == r.region[v0]) continue;
                rim_of[v] = r.region[v0];
                acc[static_cast<std::size_t>(r.region[v0] - 1)].reg.rim_m3 +=
                    std::min(std::abs(static_cast<double>(r.distance_m[v])),
                             static_cast<double>(r.lod95_m[v])) *
                    area[v];
            }
        }
    }
    const double L2 = cfg.error_correlation_length_m * cfg.error_correlation_length_m;
    GroundOffsets(m, cfg, area, u, r, acc);
    r.regions.clear();
    for (std::size_t k = 0; k < acc.size(); ++k) {
        ChangeRegion3d g = acc[k].reg;
        g.id = static_cast<int>(k + 1);
        g.direction = u[k];
        if (g.area_m2 > 0) {
            g.centroid /= g.area_m2;
            g.mean_lod95_m = acc[k].lod_a / g.area_m2;
            g.mean_slope_deg = acc[k].slope_a / g.area_m2;
        }
        g.volume_m3 += g.margin_m3 - g.ground_offset_m * acc[k].projected;
        if (acc[k].projected > 0) g.mean_distance_m = g.volume_m3 / acc[k].projected;
        g.sigma_random_m3 = std::sqrt(std::min(L2, acc[k].projected) * acc[k].sum_sigma2_a);
        g.sigma_registration_m3 =
            std::sqrt(std::max(0.0, (acc[k].sum_aJ * C * acc[k].sum_aJ.transpose())(0, 0)));
        g.u95_m3 = cfg.z95 * std::sqrt(g.sigma_random_m3 * g.sigma_random_m3 +
                                       g.sigma_registration_m3 * g.sigma_registration_m3 +
                                       g.sigma_ground_offset_m3 * g.sigma_ground_offset_m3 +
                                       g.sigma_margin_m3 * g.sigma_margin_m3) +
                   g.rim_m3;
        r.regions.push_back(g);
    }
}

// Whether the soundings' cores near p contradict a change d of sign `sign` at p: at least one
// measured core within s.radius_m, none of them significant with that sign, and d further
// than `tolerance` from their mean distance (VetoBySoundings, GrowPatches).
bool SoundingsContradict(const reg::PointIndex<double>& index,
                         const SoundingsChange& s,
                         const Eigen::Vector3d& p,
                         int sign,
                         double d,
                         double tolerance,
                         std::vector<reg::PointIndex<double>::Hit>& hits) {
    index.WithinRadius(p, s.radius_m * s.radius_m, hits);
    if (hits.empty()) return false;
    double sum = 0;
    for (const auto& [k, d2] : hits) {
        if (s.significance[k] == sign) return false;
        sum += s.distance_m[k];
    }
    return std::abs(d - sum / static_cast<double>(hits.size())) > tolerance;
}

// The kept patches grown by hysteresis (change_mesh.hpp, grow_lod_fraction): into the measured
// vertices joined to them by the mesh's edges whose distance has the patch's sign and exceeds
// grow_lod_fraction x their LoD95, and that the soundings do not contradict; unions them into
// the patch (parent). Returns the vertices added.
template <typename Find>
std::size_t GrowPatches(const TriangleMesh& m,
                        const ChangeMeshConfig& cfg,
                        const SoundingsChange* soundings,
                        Find&& find,
                        std::vector<int>& parent,
                        ChangeMeshResult& r) {
    const std::size_t n = m.vertices.size();
    if (!(cfg.grow_lod_fraction > 0)) return 0;
    // The mesh's edges as adjacency lists (CSR).
    std::vector<std::size_t> start(n + 1, 0);
    for (const auto& t : m.triangles)
        for (int k = 0; k < 3; ++k) start[static_cast<std::size_t>(t[k]) + 1] += 2;
    for (std::size_t i = 0; i < n; ++i) start[i + 1] += start[i];
    std::vector<int> adj(start[n]);
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (const auto& t : m.triangles) {
        for (int k = 0; k < 3; ++k) {
            const auto u = static_cast<std::size_t>(t[k]);
            adj[fill[u]++] = t[(k + 1) % 3];
            adj[fill[u]++] = t[(k + 2) % 3];
        }
    }
    std::optional<reg::PointIndex<double>> cores;
    if (soundings != nullptr && !soundings->position.empty())
        cores.emplace(soundings->position.data(), soundings->position.size());
    std::vector<reg::PointIndex<double>::Hit> hits;
    std::vector<int> queue;
    for (std::size_t i = 0; i < n; ++i)
        if (r.significance[i] != 0) queue.push_back(static_cast<int>(i));
    std::vector<char> refused(n, 0);    // tried and contradicted by the soundings
    std::vector<float> reach(n, 0.0f);  // along the mesh's edges from the kept patch, m
    std::size_t grown = 0;
    for (std::size_t q = 0; q < queue.size(); ++q) {
        const auto u = static_cast<std::size_t>(queue[q]);
        const int sign = r.significance[u];
        for (std::size_t e = start[u]; e < start[u + 1]; ++e) {
            const auto v = static_cast<std::size_t>(adj[e]);
            if (r.significance[v] != 0 || refused[v]) continue;
            const double step = reach[u] + (m.vertices[v] - m.vertices[u]).norm();
            if (step > cfg.grow_max_m) continue;
            const double d = r.distance_m[v];
            if (!std::isfinite(d) || d * sign <= cfg.grow_lod_fraction * r.lod95_m[v]) continue;
            if (cores && SoundingsContradict(*cores,
                                             *soundings,
                                             m.vertices[v],
                                             sign,
                                             d,
                                             cfg.grow_lod_fraction * r.lod95_m[v],
                                             hits)) {
                refused[v] = 1;
                continue;
            }
            r.significance[v] = static_cast<std::int8_t>(sign);
            reach[v] = static_cast<float>(step);
            parent[v] = find(static_cast<int>(u));
            queue.push_back(static_cast<int>(v));
            ++grown;
        }
    }
    return grown;
}

// The significant vertices in patches (one sign, joined by the mesh's edges); patches below
// the minimum area or whose mean is within their LoD set to 0; the kept ones grown
// (GrowPatches).
void TestPatches(const TriangleMesh& m,
                 const ChangeMeshConfig& cfg,
                 const std::vector<float>& sigma,
                 const RigidCorrection& T,
                 const Eigen::Matrix<double, 6, 6>& C,
                 const TriangleIndex& index,
                 const SoundingsChange* soundings,
                 ChangeMeshResult& r) {
    const std::size_t n = m.vertices.size();
    std::vector<int> parent(n);
    for (std::size_t i = 0; i < n; ++i) parent[i] = static_cast<int>(i);
    const auto find = [&](int x) {
        while (parent[static_cast<std::size_t>(x)] != x) {
            parent[static_cast<std::size_t>(x)] =
                parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
            x = parent[static_cast<std::size_t>(x)];
        }
        return x;
    };
    std::vector<double> area(n, 0.0);
    for (const auto& t : m.triangles) {
        const Eigen::Vector3d& a = m.vertices[static_cast<std::size_t>(t[0])];
        const double ta = 0.5 * (m.vertices[static_cast<std::size_t>(t[1])] - a)
                                    .cross(m.vertices[static_cast<std::size_t>(t[2])] - a)
                                    .norm();
        for (int k = 0; k < 3; ++k) {
            const auto u = static_cast<std::size_t>(t[k]);
            const auto v = static_cast<std::size_t>(t[(k + 1) % 3]);
            area[u] += ta / 3.0;
            if (r.significance[u] != 0 && r.significance[u] == r.significance[v]) {
                const int ru = find(t[k]), rv = find(t[(k + 1) % 3]);
                if (ru != rv) parent[static_cast<std::size_t>(ru)] = rv;
            }
        }
    }
    struct Patch {
        double area = 0, sum_d = 0, sum_lod2 = 0;
        std::size_t count = 0;
    };
    std::vector<Patch> patch(n);
    for (std::size_t i = 0; i < n; ++i) {
        if (r.significance[i] == 0) continue;
        Patch& p = patch[static_cast<std::size_t>(find(static_cast<int>(i)))];
        p.area += area[i];
        p.sum_d += r.distance_m[i];
        p.sum_lod2 += static_cast<double>(r.lod95_m[i]) * r.lod95_m[i];
        ++p.count;
    }
    std::vector<char> keep(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        const Patch& p = patch[i];
        if (p.count == 0) continue;
        const double c = static_cast<double>(p.count);
        const bool ok = p.area >= cfg.min_patch_area_m2 &&
                        (!cfg.test_patch_mean || std::abs(p.sum_d / c) > std::sqrt(p.sum_lod2 / c));
        keep[i] = ok ? 1 : 0;
        ++(ok ? r.patches : r.patches_dropped);
    }
    for (std::size_t i = 0; i < n; ++i) {
        if (r.significance[i] != 0 && !keep[static_cast<std::size_t>(find(static_cast<int>(i)))])
            r.significance[i] = 0;
    }
    r.grown = GrowPatches(m, cfg, soundings, find, parent, r);
    r.gain = r.loss = 0;
    for (std::size_t i = 0; i < n; ++i) {
        if (r.significance[i] != 0) ++(r.significance[i] > 0 ? r.gain : r.loss);
    }
    Regions(m, cfg, area, sigma, T, C, index, find, r);
}

// The significant vertices the soundings contradict set to 0 (ComputeChangeMesh).
void VetoBySoundings(const TriangleMesh& m, const SoundingsChange& s, ChangeMeshResult& r) {
    if (s.position.empty()) return;
    const reg::PointIndex<double> index(s.position.data(), s.position.size());
    std::vector<reg::PointIndex<double>::Hit> hits;
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
        const int sign = r.significance[i];
        if (sign == 0) continue;
        if (!SoundingsContradict(
                index, s, m.vertices[i], sign, r.distance_m[i], r.lod95_m[i], hits))
            continue;
        r.significance[i] = 0;
        --(sign > 0 ? r.gain : r.loss);
        ++r.vetoed_by_soundings;
    }
}

}  // namespace

std::vector<std::string> ChangeMeshConfig::Validate() const {
    std::vector<std::string> p;
    if (!(max_distance_m > 0)) p.push_back("change_mesh.max_distance_m must be > 0");
    if (!(cell_m > 0)) p.push_back("change_mesh.cell_m must be > 0");
    if (!(z95 > 0)) p.push_back("change_mesh.z95 must be > 0");
    if (!(min_patch_area_m2 >= 0)) p.push_back("change_mesh.min_patch_area_m2 must be >= 0");
    if (!(error_correlation_length_m >= 0))
        p.push_back("change_mesh.error_correlation_length_m must be >= 0");
    if (!(ground_band_inner_m >= 0) || !(ground_band_outer_m > ground_band_inner_m))
        p.push_back("change_mesh.ground_band_inner_m must be >= 0 and below ground_band_outer_m");
    if (!(margin_band_m >= 0) || !(margin_band_m <= ground_band_outer_m))
        p.push_back("change_mesh.margin_band_m must be in [0, ground_band_outer_m]");
    if (!(grow_lod_fraction >= 0) || !(grow_lod_fraction <= 1))
        p.push_back("change_mesh.grow_lod_fraction must be in [0, 1]");
    if (!(grow_max_m >= 0)) p.push_back("change_mesh.grow_max_m must be >= 0");
    if (!(ground_band_max_angle_deg > 0) || !(ground_band_max_angle_deg <= 90))
        p.push_back("change_mesh.ground_band_max_angle_deg must be in (0, 90]");
    return p;
}

std::size_t ConfirmRegionsBySoundings(const TriangleMesh& b,
                                      const std::vector<Eigen::Vector3d>& core_positions,
                                      const std::vector<int>& core_significance,
                                      double radius_m,
                                      double min_share,
                                      ChangeMeshResult& r) {
    if (r.regions.empty() || core_positions.empty()) return 0;
    const reg::PointIndex<double> index(core_positions.data(), core_positions.size());
    const std::size_t nreg = r.regions.size();
    // Per region: the measured cores near it (each once), and those of its sign.
    std::vector<std::unordered_set<std::size_t>> near(nreg);
    std::vector<reg::PointIndex<double>::Hit> hits;
    for (std::size_t i = 0; i < b.vertices.size(); ++i) {
        if (r.region[i] == 0) continue;
        index.WithinRadius(b.vertices[i], radius_m * radius_m, hits);
        for (const auto& [k, d2] : hits) near[static_cast<std::size_t>(r.region[i] - 1)].insert(k);
    }
    std::vector<int> new_id(nreg + 1, 0);
    std::vector<ChangeRegion3d> kept;
    for (std::size_t g = 0; g < nreg; ++g) {
        std::size_t same = 0;
        for (std::size_t k : near[g]) same += core_significance[k] == r.regions[g].sign;
        const bool ok = !near[g].empty() && static_cast<double>(same) >=
                                                min_share * static_cast<double>(near[g].size());
        if (!ok) continue;
        kept.push_back(r.regions[g]);
        kept.back().id = static_cast<int>(kept.size());
        new_id[g + 1] = kept.back().id;
    }
    const std::size_t dropped = nreg - kept.size();
    r.regions = std::move(kept);
    r.gain = r.loss = 0;
    for (std::size_t i = 0; i < r.region.size(); ++i) {
        if (r.region[i] == 0) continue;
        r.region[i] = new_id[static_cast<std::size_t>(r.region[i])];
        if (r.region[i] == 0) {
            r.significance[i] = 0;
            continue;
        }
        ++(r.significance[i] > 0 ? r.gain : r.loss);
    }
    r.patches = r.regions.size();
    r.regions_unconfirmed += dropped;
    return dropped;
}

ChangeMeshResult ComputeChangeMesh(const TriangleMesh& b,
                                   const TriangleMesh& a,
                                   const RigidCorrection& T,
                                   const Eigen::Matrix<double, 6, 6>& C,
                                   const ChangeMeshConfig& cfg,
                                   const std::function<double(const Eigen::Vector3d&)>& sigma_ab,
                                   const SoundingsChange* soundings) {
    ChangeMeshResult r;
    const std::size_t n = b.vertices.size();
    r.normals = VertexNormals(b, &r.flipped);
    r.distance_m.assign(n, kNaNf);
    r.lod95_m.assign(n, kNaNf);
    r.significance.assign(n, 0);
    std::vector<float> sigma(n, 0.0f);
    std::vector<double> lods;
    const TriangleIndex index(a, cfg.cell_m);
    if (!a.triangles.empty()) {
        for (std::size_t i = 0; i < n; ++i) {
            const Eigen::Vector3d nrm = r.normals[i].cast<double>();
            if (nrm.squaredNorm() < 0.5) continue;
            const Eigen::Vector3d& p = b.vertices[i];
            const double t = index.Hit(p, nrm, cfg.max_distance_m);
            if (!std::isfinite(t)) continue;
            Eigen::Matrix<double, 1, 6> J;
            J.head<3>() = ((p - T.pivot).cross(nrm)).transpose();
            J.tail<3>() = nrm.transpose();
            double s = sigma_ab ? sigma_ab(p) : 0.0;
            if (!std::isfinite(s)) s = 0.0;
            sigma[i] = static_cast<float>(s);
            const double lod =
                cfg.z95 * std::sqrt(s * s + std::max(0.0, (J * C * J.transpose())(0, 0)));
            const double d = -t;
            r.distance_m[i] = static_cast<float>(d);
            r.lod95_m[i] = static_cast<float>(lod);
            if (std::abs(d) > lod) {
                r.significance[i] = d > 0 ? 1 : -1;
                ++(d > 0 ? r.gain : r.loss);
            }
            lods.push_back(lod);
            ++r.measured;
        }
    }
    if (soundings != nullptr) VetoBySoundings(b, *soundings, r);
    TestPatches(b, cfg, sigma, T, C, index, soundings, r);
    if (!lods.empty()) {
        std::nth_element(
            lods.begin(), lods.begin() + static_cast<std::ptrdiff_t>(lods.size() / 2), lods.end());
        r.median_lod95_m = lods[lods.size() / 2];
    }
    char buf[400];
    std::snprintf(buf,
                  sizeof buf,
                  "%zu of %zu vertices of B's mesh measured against A's along their normal, %zu "
                  "gain and %zu loss beyond the LoD95 (median %.3f m) in %zu patches (%zu "
                  "dropped: small or below detection as a whole; %zu vertices the soundings "
                  "contradict)%s",
                  r.measured,
                  n,
                  r.gain,
                  r.loss,
                  r.median_lod95_m,
                  r.patches,
                  r.patches_dropped,
                  r.vetoed_by_soundings,
                  r.flipped ? "; B's mesh was wound into the ground: normals turned over" : "");
    r.message = buf;
    return r;
}

}  // namespace pitmap::proc::compare
