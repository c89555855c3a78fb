// SPDX-License-Identifier: MIT
#include "processor/compare/change_mesh.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

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

// The significant vertices in patches (one sign, joined by the mesh's edges); patches below
// the minimum area or whose mean is within their LoD set to 0.
void TestPatches(const TriangleMesh& m, const ChangeMeshConfig& cfg, ChangeMeshResult& r) {
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
    r.gain = r.loss = 0;
    for (std::size_t i = 0; i < n; ++i) {
        if (r.significance[i] == 0) continue;
        if (!keep[static_cast<std::size_t>(find(static_cast<int>(i)))]) {
            r.significance[i] = 0;
            continue;
        }
        ++(r.significance[i] > 0 ? r.gain : r.loss);
    }
}

}  // namespace

std::vector<std::string> ChangeMeshConfig::Validate() const {
    std::vector<std::string> p;
    if (!(max_distance_m > 0)) p.push_back("change_mesh.max_distance_m must be > 0");
    if (!(cell_m > 0)) p.push_back("change_mesh.cell_m must be > 0");
    if (!(z95 > 0)) p.push_back("change_mesh.z95 must be > 0");
    if (!(min_patch_area_m2 >= 0)) p.push_back("change_mesh.min_patch_area_m2 must be >= 0");
    return p;
}

ChangeMeshResult ComputeChangeMesh(const TriangleMesh& b,
                                   const TriangleMesh& a,
                                   const RigidCorrection& T,
                                   const Eigen::Matrix<double, 6, 6>& C,
                                   const ChangeMeshConfig& cfg,
                                   const std::function<double(const Eigen::Vector3d&)>& sigma_ab) {
    ChangeMeshResult r;
    const std::size_t n = b.vertices.size();
    r.normals = VertexNormals(b, &r.flipped);
    r.distance_m.assign(n, kNaNf);
    r.lod95_m.assign(n, kNaNf);
    r.significance.assign(n, 0);
    std::vector<double> lods;
    if (!a.triangles.empty()) {
        const TriangleIndex index(a, cfg.cell_m);
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
    TestPatches(b, cfg, r);
    if (!lods.empty()) {
        std::nth_element(
            lods.begin(), lods.begin() + static_cast<std::ptrdiff_t>(lods.size() / 2), lods.end());
        r.median_lod95_m = lods[lods.size() / 2];
    }
    char buf[320];
    std::snprintf(buf,
                  sizeof buf,
                  "%zu of %zu vertices of B's mesh measured against A's along their normal, %zu "
                  "gain and %zu loss beyond the LoD95 (median %.3f m) in %zu patches (%zu "
                  "dropped: small or below detection as a whole)%s",
                  r.measured,
                  n,
                  r.gain,
                  r.loss,
                  r.median_lod95_m,
                  r.patches,
                  r.patches_dropped,
                  r.flipped ? "; B's mesh was wound into the ground: normals turned over" : "");
    r.message = buf;
    return r;
}

}  // namespace pitmap::proc::compare
