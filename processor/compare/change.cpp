// SPDX-License-Identifier: MIT
#include "processor/compare/change.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <unordered_map>

namespace pitmap::proc::compare {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
using Row6 = Eigen::Matrix<double, 1, 6>;

using Ring = std::vector<Eigen::Vector2d>;

double SignedArea(const Ring& r) {
    double a = 0;
    for (std::size_t k = 0; k + 1 < r.size(); ++k)
        a += r[k].x() * r[k + 1].y() - r[k + 1].x() * r[k].y();
    return 0.5 * a;
}

bool Inside(const Ring& ring, const Eigen::Vector2d& p) {
    bool in = false;
    for (std::size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++) {
        const auto& a = ring[i];
        const auto& b = ring[j];
        if ((a.y() > p.y()) != (b.y() > p.y()) &&
            p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
            in = !in;
    }
    return in;
}

// The outline of the nodes labelled `id` along their cells' edges: outer rings counter-
// clockwise with their holes (clockwise) after them, one polygon per outer ring.
std::vector<std::vector<Ring>> TraceOutline(
    const SurfaceGrid& g, const std::vector<int>& label, int id, int i0, int i1, int j0, int j1) {
    struct Edge {
        int ax, ay, bx, by;
        bool used = false;
    };
    std::vector<Edge> edges;
    const auto in = [&](int i, int j) {
        return i >= 0 && j >= 0 && i < g.nx && j < g.ny && label[g.index(i, j)] == id;
    };
    for (int j = j0; j <= j1; ++j) {
        for (int i = i0; i <= i1; ++i) {
            if (!in(i, j)) continue;
            // Corners (i, j) .. (i + 1, j + 1) around the cell, counter-clockwise.
            if (!in(i, j - 1)) edges.push_back({i, j, i + 1, j});
            if (!in(i + 1, j)) edges.push_back({i + 1, j, i + 1, j + 1});
            if (!in(i, j + 1)) edges.push_back({i + 1, j + 1, i, j + 1});
            if (!in(i - 1, j)) edges.push_back({i, j + 1, i, j});
        }
    }
    const auto key = [](int x, int y) {
        return (static_cast<std::int64_t>(x) << 32) ^ static_cast<std::uint32_t>(y);
    };
    std::unordered_multimap<std::int64_t, std::size_t> from;
    for (std::size_t k = 0; k < edges.size(); ++k) from.emplace(key(edges[k].ax, edges[k].ay), k);
    std::vector<Ring> outers, holes;
    for (std::size_t start = 0; start < edges.size(); ++start) {
        if (edges[start].used) continue;
        std::vector<std::pair<int, int>> corners;
        std::size_t e = start;
        while (!edges[e].used) {
            edges[e].used = true;
            corners.emplace_back(edges[e].ax, edges[e].ay);
            const auto range = from.equal_range(key(edges[e].bx, edges[e].by));
            std::size_t next = e;
            // At a corner where two cells of the region touch diagonally: take the right turn,
            // so the ring goes on around the diagonal neighbour (8-connectivity, as the regions
            // are labelled; any choice closes the ring).
            const int dx = edges[e].bx - edges[e].ax, dy = edges[e].by - edges[e].ay;
            for (auto it = range.first; it != range.second; ++it) {
                if (edges[it->second].used) continue;
                const Edge& c = edges[it->second];
                const int cx = c.bx - c.ax, cy = c.by - c.ay;
                next = it->second;
                if (dx * cy - dy * cx < 0) break;  // right turn
            }
            if (next == e) break;
            e = next;
        }
        Ring ring;
        const std::size_t n = corners.size();
        for (std::size_t k = 0; k < n; ++k) {
            // Drop corners on a straight line.
            const auto& p = corners[(k + n - 1) % n];
            const auto& c = corners[k];
            const auto& q = corners[(k + 1) % n];
            if ((c.first - p.first) * (q.second - c.second) -
                    (c.second - p.second) * (q.first - c.first) ==
                0)
                continue;
            ring.emplace_back(g.x0 + (c.first - 0.5) * g.resolution_m,
                              g.y0 + (c.second - 0.5) * g.resolution_m);
        }
        if (ring.size() < 3) continue;
        ring.push_back(ring.front());
        (SignedArea(ring) > 0 ? outers : holes).push_back(std::move(ring));
    }
    std::sort(outers.begin(), outers.end(), [](const Ring& x, const Ring& y) {
        return SignedArea(x) > SignedArea(y);
    });
    std::vector<std::vector<Ring>> polygons;
    for (Ring& o : outers) polygons.push_back({std::move(o)});
    for (Ring& h : holes) {
        for (auto& poly : polygons) {
            if (Inside(poly.front(), h.front())) {
                poly.push_back(std::move(h));
                break;
            }
        }
    }
    return polygons;
}

// Per compared node of A: the random variance of B - A and the row that carries the
// correction's covariance into it (zero where not compared).
struct NodeTerms {
    std::vector<float> var_ab;
    std::vector<Row6> J;
};

double MedianInPlace(std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
}

// B - A and its level of detection at A's filled nodes, the medians of the latter (all and by
// slope class) and the compared nodes into r.
NodeTerms DifferenceNodes(const SurfaceGrid& a,
                          const SurfaceGrid& b,
                          const RigidCorrection& T,
                          const Eigen::Matrix<double, 6, 6>& C,
                          const ChangeConfig& cfg,
                          ChangeResult& r) {
    const std::size_t n = a.z_m.size();
    NodeTerms t;
    t.var_ab.assign(n, 0.0f);
    t.J.assign(n, Row6::Zero());
    const int grad_step = std::max(1, static_cast<int>(std::lround(0.2 / a.resolution_m)));
    std::vector<double> lods;
    std::vector<double> lods_by_slope[3];
    for (int j = 0; j < a.ny; ++j) {
        for (int i = 0; i < a.nx; ++i) {
            const std::size_t k = a.index(i, j);
            if (!a.filled(i, j)) continue;
            const double x = a.x0 + i * a.resolution_m, y = a.y0 + j * a.resolution_m;
            const Eigen::Vector3d q = T.CarryOnto(b, x, y);
            if (!std::isfinite(q.z())) continue;
            // B's sigma where the node came from (close enough: the correction is small).
            const double sb = b.SigmaAt(x, y);
            const double sa = a.sigma_m[k];
            const double var = (std::isfinite(sa) ? sa * sa : 0.0) +
                               (std::isfinite(sb) ? sb * sb : (std::isfinite(sa) ? sa * sa : 0.0));
            Eigen::Vector2d g = GradientAt(a, i, j, grad_step);
            if (!std::isfinite(g.x()) || !std::isfinite(g.y())) g.setZero();
            const Eigen::Vector3d m(-g.x(), -g.y(), 1.0);
            const Eigen::Vector3d p(x, y, a.z_m[k]);
            t.J[k].head<3>() = ((p - T.pivot).cross(m)).transpose();
            t.J[k].tail<3>() = m.transpose();
            const double var_reg = (t.J[k] * C * t.J[k].transpose())(0, 0);
            const double lod = cfg.z95 * std::sqrt(var + std::max(0.0, var_reg));
            r.difference_m[k] = static_cast<float>(q.z() - a.z_m[k]);
            r.lod95_m[k] = static_cast<float>(lod);
            t.var_ab[k] = static_cast<float>(var);
            lods.push_back(lod);
            const double slope_deg = std::atan(g.norm()) * 57.29577951308232;
            lods_by_slope[slope_deg < 20 ? 0 : (slope_deg < 45 ? 1 : 2)].push_back(lod);
            ++r.compared_nodes;
        }
    }
    const double cell = a.resolution_m * a.resolution_m;
    r.compared_area_m2 = static_cast<double>(r.compared_nodes) * cell;
    if (!lods.empty()) r.median_lod95_m = MedianInPlace(lods);
    for (int c = 0; c < 3; ++c) {
        auto& v = lods_by_slope[c];
        if (v.empty()) continue;
        (c == 0   ? r.median_lod95_floor_m
         : c == 1 ? r.median_lod95_face_m
                  : r.median_lod95_wall_m) = MedianInPlace(v);
    }
    return t;
}

// The sign of the change per node (0 none): seeds beyond the level of detection, grown by
// hysteresis to neighbours beyond grow_fraction of theirs.
std::vector<int> GrowChangeSigns(const SurfaceGrid& a,
                                 const ChangeResult& r,
                                 const ChangeConfig& cfg) {
    std::vector<int> sign(a.z_m.size(), 0);
    std::vector<std::pair<int, int>> queue;
    for (int j = 0; j < a.ny; ++j) {
        for (int i = 0; i < a.nx; ++i) {
            const std::size_t k = a.index(i, j);
            const float d = r.difference_m[k];
            if (!std::isfinite(d)) continue;
            if (std::abs(d) > r.lod95_m[k]) {
                sign[k] = d > 0 ? 1 : -1;
                queue.emplace_back(i, j);
            }
        }
    }
    for (std::size_t head = 0; head < queue.size(); ++head) {
        const auto [i, j] = queue[head];
        const int s = sign[a.index(i, j)];
        for (int dj = -1; dj <= 1; ++dj) {
            for (int di = -1; di <= 1; ++di) {
                const int u = i + di, v = j + dj;
                if (u < 0 || v < 0 || u >= a.nx || v >= a.ny) continue;
                const std::size_t k = a.index(u, v);
                if (sign[k] != 0 || !std::isfinite(r.difference_m[k])) continue;
                if (r.difference_m[k] * s > cfg.grow_fraction * r.lod95_m[k]) {
                    sign[k] = s;
                    queue.emplace_back(u, v);
                }
            }
        }
    }
    return sign;
}

// One connected region of one sign, summed.
struct RegionAcc {
    int sign = 0;
    std::size_t nodes = 0;
    double volume = 0, var_rand = 0, max_abs = 0, lod_sum = 0, rim = 0;
    Row6 jsum = Row6::Zero();
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    int i0 = 1 << 30, i1 = -1, j0 = 1 << 30, j1 = -1;
};

// The regions: label per node (0 none), acc[label] (acc[0] unused).
struct Components {
    std::vector<int> label;
    std::vector<RegionAcc> acc;
};

// Components by 8-connectivity per sign, summed.
Components LabelRegions(const SurfaceGrid& a,
                        const std::vector<int>& sign,
                        const ChangeResult& r,
                        const NodeTerms& t) {
    const double cell = a.resolution_m * a.resolution_m;
    Components out;
    std::vector<int>& label = out.label;
    label.assign(a.z_m.size(), 0);
    int next_label = 0;
    out.acc.resize(1);
    std::vector<std::pair<int, int>> stack;
    for (int j = 0; j < a.ny; ++j) {
        for (int i = 0; i < a.nx; ++i) {
            const std::size_t k0 = a.index(i, j);
            if (sign[k0] == 0 || label[k0] != 0) continue;
            const int id = ++next_label;
            RegionAcc c;
            c.sign = sign[k0];
            label[k0] = id;
            stack.assign(1, {i, j});
            while (!stack.empty()) {
                const auto [u, v] = stack.back();
                stack.pop_back();
                const std::size_t k = a.index(u, v);
                ++c.nodes;
                c.volume += r.difference_m[k] * cell;
                c.var_rand += t.var_ab[k];
                c.max_abs = std::max(c.max_abs, static_cast<double>(std::abs(r.difference_m[k])));
                c.lod_sum += r.lod95_m[k];
                c.jsum += t.J[k];
                c.centroid += Eigen::Vector2d(a.x0 + u * a.resolution_m, a.y0 + v * a.resolution_m);
                c.i0 = std::min(c.i0, u);
                c.i1 = std::max(c.i1, u);
                c.j0 = std::min(c.j0, v);
                c.j1 = std::max(c.j1, v);
                for (int dj = -1; dj <= 1; ++dj) {
                    for (int di = -1; di <= 1; ++di) {
                        const int x = u + di, y = v + dj;
                        if (x < 0 || y < 0 || x >= a.nx || y >= a.ny) continue;
                        const std::size_t q = a.index(x, y);
                        if (sign[q] == c.sign && label[q] == 0) {
                            label[q] = id;
                            stack.emplace_back(x, y);
                        }
                    }
                }
            }
            out.acc.push_back(c);
        }
    }
    return out;
}

// The rim: nodes bordering a region (4-neighbours outside it) with a difference.
void AddRims(const SurfaceGrid& a, const ChangeResult& r, Components& comps) {
    const double cell = a.resolution_m * a.resolution_m;
    const std::vector<int>& label = comps.label;
    for (int j = 0; j < a.ny; ++j) {
        for (int i = 0; i < a.nx; ++i) {
            const std::size_t k = a.index(i, j);
            if (label[k] != 0 || !std::isfinite(r.difference_m[k])) continue;
            int seen[4] = {0, 0, 0, 0};
            int ns = 0;
            const int nb[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
            for (const auto& d : nb) {
                const int x = i + d[0], y = j + d[1];
                if (x < 0 || y < 0 || x >= a.nx || y >= a.ny) continue;
                const int id = label[a.index(x, y)];
                if (id == 0 || std::find(seen, seen + ns, id) != seen + ns) continue;
                seen[ns++] = id;
                comps.acc[static_cast<std::size_t>(id)].rim +=
                    std::min(std::abs(r.difference_m[k]), r.lod95_m[k]) * cell;
            }
        }
    }
}

// Nodes within one error correlation patch.
double PatchNodes(const SurfaceGrid& a, const ChangeConfig& cfg) {
    return std::max(1.0, std::pow(cfg.error_correlation_length_m / a.resolution_m, 2.0));
}

// The regions of at least min_region_area_m2 into r.regions, numbered from 1; returns the
// kept id per label (0: dropped).
std::vector<int> KeepRegions(const SurfaceGrid& a,
                             const Components& comps,
                             const Eigen::Matrix<double, 6, 6>& C,
                             const ChangeConfig& cfg,
                             ChangeResult& r) {
    const double cell = a.resolution_m * a.resolution_m;
    const double n_c_patch = PatchNodes(a, cfg);
    std::vector<int> kept_id(comps.acc.size(), 0);
    int kept = 0;
    for (std::size_t id = 1; id < comps.acc.size(); ++id) {
        const RegionAcc& c = comps.acc[id];
        const double area = static_cast<double>(c.nodes) * cell;
        if (area < cfg.min_region_area_m2) continue;
        // The region as a whole: its mean against the LoD of a mean of shared errors.
        const double nodes = static_cast<double>(c.nodes);
        const double mean_dz = c.volume / (nodes * cell);
        const Row6 jmean = c.jsum / nodes;
        const double region_lod =
            cfg.z95 *
            std::sqrt(c.var_rand / nodes + std::max(0.0, (jmean * C * jmean.transpose())(0, 0)));
        if (cfg.test_region_mean && !(std::abs(mean_dz) > region_lod)) {
            ++r.regions_below_detection;
            r.area_below_detection_m2 += area;
            continue;
        }
        ChangeRegion reg;
        reg.id = ++kept;
        kept_id[id] = reg.id;
        reg.sign = c.sign;
        reg.nodes = c.nodes;
        reg.area_m2 = area;
        reg.volume_m3 = c.volume;
        const double n_c = std::min(n_c_patch, static_cast<double>(c.nodes));
        reg.sigma_random_m3 = std::sqrt(n_c * c.var_rand) * cell;
        reg.sigma_registration_m3 =
            std::sqrt(std::max(0.0, (c.jsum * C * c.jsum.transpose())(0, 0))) * cell;
        reg.rim_m3 = c.rim;
        reg.u95_m3 =
            cfg.z95 * std::hypot(reg.sigma_random_m3, reg.sigma_registration_m3) + reg.rim_m3;
        reg.max_abs_difference_m = c.max_abs;
        reg.mean_lod95_m = c.lod_sum / static_cast<double>(c.nodes);
        reg.mean_difference_m = mean_dz;
        reg.region_lod95_m = region_lod;
        reg.centroid = c.centroid / static_cast<double>(c.nodes);
        reg.polygons = TraceOutline(a, comps.label, static_cast<int>(id), c.i0, c.i1, c.j0, c.j1);
        r.regions.push_back(std::move(reg));
    }
    return kept_id;
}

// Dodd's band values (region, significance) and the stable statistics into r.
void BandsAndStableTerrain(const std::vector<int>& sign,
                           const std::vector<int>& label,
                           const std::vector<int>& kept_id,
                           ChangeResult& r) {
    double stable_sum = 0, stable_sum2 = 0;
    std::size_t stable_n = 0, in_region = 0;
    for (std::size_t k = 0; k < r.difference_m.size(); ++k) {
        if (!std::isfinite(r.difference_m[k])) continue;
        const int id = label[k] != 0 ? kept_id[static_cast<std::size_t>(label[k])] : 0;
        r.region[k] = static_cast<float>(id);
        r.significance[k] = id != 0 ? static_cast<float>(sign[k]) : 0.0f;
        if (id != 0) {
            ++in_region;
        } else {
            stable_sum += r.difference_m[k];
            stable_sum2 += static_cast<double>(r.difference_m[k]) * r.difference_m[k];
            ++stable_n;
        }
    }
    if (stable_n > 0) {
        r.stable_mean_m = stable_sum / static_cast<double>(stable_n);
        r.stable_rms_m = std::sqrt(stable_sum2 / static_cast<double>(stable_n));
    }
    r.significant_share = r.compared_nodes > 0 ? static_cast<double>(in_region) /
                                                     static_cast<double>(r.compared_nodes)
                                               : 0.0;
}

// Totals: random terms in quadrature, registration (one correction) and rims linearly.
void CutFillTotals(const SurfaceGrid& a,
                   const Components& comps,
                   const std::vector<int>& kept_id,
                   const Eigen::Matrix<double, 6, 6>& C,
                   const ChangeConfig& cfg,
                   ChangeResult& r) {
    const double cell = a.resolution_m * a.resolution_m;
    const double n_c_patch = PatchNodes(a, cfg);
    const std::vector<RegionAcc>& acc = comps.acc;
    for (ChangeTotals* t : {&r.cut, &r.fill}) {
        const int s = t == &r.cut ? -1 : 1;
        double var_rand = 0, rim = 0;
        Row6 jsum = Row6::Zero();
        for (std::size_t id = 1; id < acc.size(); ++id) {
            if (kept_id[id] == 0 || acc[id].sign != s) continue;
            const double n_c = std::min(n_c_patch, static_cast<double>(acc[id].nodes));
            var_rand += n_c * acc[id].var_rand * cell * cell;
            jsum += acc[id].jsum;
            rim += acc[id].rim;
            t->volume_m3 += acc[id].volume;
            t->area_m2 += static_cast<double>(acc[id].nodes) * cell;
            ++t->regions;
        }
        const double sreg = std::sqrt(std::max(0.0, (jsum * C * jsum.transpose())(0, 0))) * cell;
        t->u95_m3 = cfg.z95 * std::sqrt(var_rand + sreg * sreg) + rim;
    }
}

std::string ChangeMessage(const ChangeResult& r) {
    char buf[400];
    std::snprintf(buf,
                  sizeof buf,
                  "%zu nodes compared (%.0f m2), median LoD95 %.3f m; %zu regions: cut %.2f +- "
                  "%.2f m3 (%d), fill %.2f +- %.2f m3 (%d); %d regions (%.1f m2) below detection "
                  "as a whole; stable terrain %.3f m mean, %.3f m RMS",
                  r.compared_nodes,
                  r.compared_area_m2,
                  r.median_lod95_m,
                  r.regions.size(),
                  r.cut.volume_m3,
                  r.cut.u95_m3,
                  r.cut.regions,
                  r.fill.volume_m3,
                  r.fill.u95_m3,
                  r.fill.regions,
                  r.regions_below_detection,
                  r.area_below_detection_m2,
                  r.stable_mean_m,
                  r.stable_rms_m);
    return buf;
}

}  // namespace

std::vector<std::string> ChangeConfig::Validate() const {
    std::vector<std::string> p;
    if (!(z95 > 0)) p.push_back("change.z95 must be > 0");
    if (!(grow_fraction > 0 && grow_fraction <= 1)) p.push_back("change.grow_fraction: (0, 1]");
    if (!(min_region_area_m2 >= 0)) p.push_back("change.min_region_area_m2 must be >= 0");
    if (!(error_correlation_length_m > 0))
        p.push_back("change.error_correlation_length_m must be > 0");
    return p;
}

ChangeResult ComputeChange(const SurfaceGrid& a,
                           const SurfaceGrid& b,
                           const RigidCorrection& T,
                           const Eigen::Matrix<double, 6, 6>& C,
                           const ChangeConfig& cfg) {
    ChangeResult r;
    const std::size_t n = a.z_m.size();
    r.difference_m.assign(n, kNaNf);
    r.lod95_m.assign(n, kNaNf);
    r.significance.assign(n, kNaNf);
    r.region.assign(n, kNaNf);
    const NodeTerms terms = DifferenceNodes(a, b, T, C, cfg, r);
    const std::vector<int> sign = GrowChangeSigns(a, r, cfg);
    Components comps = LabelRegions(a, sign, r, terms);
    AddRims(a, r, comps);
    const std::vector<int> kept_id = KeepRegions(a, comps, C, cfg, r);
    BandsAndStableTerrain(sign, comps.label, kept_id, r);
    CutFillTotals(a, comps, kept_id, C, cfg, r);
    std::sort(r.regions.begin(), r.regions.end(), [](const ChangeRegion& x, const ChangeRegion& y) {
        return std::abs(x.volume_m3) > std::abs(y.volume_m3);
    });
    r.message = ChangeMessage(r);
    return r;
}

}  // namespace pitmap::proc::compare
