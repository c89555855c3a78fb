// SPDX-License-Identifier: MIT
#include "processor/mesh/surface.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <tbb/parallel_sort.h>

namespace pitmap::proc::mesh {

namespace {

void Colourise(ColouredMesh& m, double lo, double hi) {
    m.colours.resize(m.vertices.size());
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
        m.colours[i] = DepthColour(m.vertices[i].z(), lo, hi);
    }
}

}  // namespace

std::vector<std::string> MeshConfig::Validate() const {
    std::vector<std::string> problems;
    if (!std::isfinite(iso_m)) problems.push_back("iso_m must be finite");
    if (max_hole_edges < 0) problems.push_back("max_hole_edges must be >= 0 (0 = no filling)");
    if (!std::isfinite(colour_min_z_m) || !std::isfinite(colour_max_z_m)) {
        problems.push_back("colour_min_z_m and colour_max_z_m must be finite");
    } else if (colour_max_z_m < colour_min_z_m) {
        problems.push_back("colour_max_z_m must be >= colour_min_z_m");
    }
    return problems;
}

std::array<std::uint8_t, 3> DepthColour(double z_m, double min_z_m, double max_z_m) {
    // Five stops from deep to shallow: dark blue, cyan, green, yellow, red.
    static constexpr double kStops[5][3] = {{0.10, 0.10, 0.50},
                                            {0.00, 0.65, 0.90},
                                            {0.20, 0.80, 0.30},
                                            {0.95, 0.90, 0.20},
                                            {0.85, 0.20, 0.10}};
    double t = max_z_m > min_z_m ? (z_m - min_z_m) / (max_z_m - min_z_m) : 0.5;
    t = std::clamp(t, 0.0, 1.0) * 4.0;
    const int k = std::min(3, static_cast<int>(t));
    const double a = t - k;
    std::array<std::uint8_t, 3> rgb{};
    for (int c = 0; c < 3; ++c) {
        const double v = (1.0 - a) * kStops[k][c] + a * kStops[k + 1][c];
        rgb[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(std::lround(v * 255.0));
    }
    return rgb;
}

double MeshArea(const std::vector<Eigen::Vector3f>& vertices,
                const std::vector<Eigen::Vector3i>& triangles) {
    double area = 0;
    for (const Eigen::Vector3i& t : triangles) {
        const Eigen::Vector3d a = vertices[static_cast<std::size_t>(t[0])].cast<double>();
        const Eigen::Vector3d b = vertices[static_cast<std::size_t>(t[1])].cast<double>();
        const Eigen::Vector3d c = vertices[static_cast<std::size_t>(t[2])].cast<double>();
        area += 0.5 * (b - a).cross(c - a).norm();
    }
    return area;
}

HoleFillResult FillSmallHoles(std::vector<Eigen::Vector3f>& vertices,
                              std::vector<Eigen::Vector3i>& triangles,
                              int max_edges) {
    HoleFillResult r;
    // Per-vertex arrays below: a triangle with an index outside the vertices (not one the
    // iso-surface makes) is left out of the boundary search rather than read out of bounds.
    const std::size_t nv = vertices.size();
    auto valid = [nv](const Eigen::Vector3i& t) {
        return t.minCoeff() >= 0 && static_cast<std::size_t>(t.maxCoeff()) < nv;
    };
    // Directed edges a->b as (min, max, a > b), sorted: both directions of an edge are
    // neighbours there, so a boundary edge (a->b without b->a) is one without its twin, found in
    // one pass (a hash map of the edges took ~0.5 GB on bejanca's 3 M triangles, a binary search
    // for each twin was most of this function's time). Vertex ids are below 2^31.
    std::vector<std::uint64_t> directed;
    directed.reserve(triangles.size() * 3);
    for (const Eigen::Vector3i& t : triangles) {
        if (!valid(t)) continue;
        for (int k = 0; k < 3; ++k) {
            const auto a = static_cast<std::uint64_t>(t[k]);
            const auto b = static_cast<std::uint64_t>(t[(k + 1) % 3]);
            if (a == b) continue;  // a degenerate edge bounds nothing
            directed.push_back(a < b ? (a << 32) | (b << 1) : (b << 32) | (a << 1) | 1u);
        }
    }
    tbb::parallel_sort(directed.begin(), directed.end());
    directed.erase(std::unique(directed.begin(), directed.end()), directed.end());
    // The fill must contain the reverse of each boundary edge: walk b -> a. A start vertex with
    // several boundary edges (non-manifold) keeps the one from the largest a; its loop is
    // ambiguous. Flat arrays by vertex id.
    constexpr int kNone = -1;
    std::vector<int> next(nv, kNone);            // start vertex -> end vertex (reversed edge)
    std::vector<std::uint8_t> out_count(nv, 0);  // boundary edges from it, saturating at 2
    for (std::size_t i = 0; i < directed.size(); ++i) {
        const std::uint64_t key = directed[i];
        if (i + 1 < directed.size() && (directed[i + 1] >> 1) == (key >> 1)) {
            ++i;  // both directions: an interior edge
            continue;
        }
        const auto lo = static_cast<int>(key >> 32);
        const auto hi = static_cast<int>((key >> 1) & 0x7fffffffu);
        const int a = (key & 1u) != 0 ? hi : lo;
        const int b = (key & 1u) != 0 ? lo : hi;
        auto& nb = next[static_cast<std::size_t>(b)];
        nb = std::max(nb, a);
        auto& oc = out_count[static_cast<std::size_t>(b)];
        oc = static_cast<std::uint8_t>(std::min(2, oc + 1));
    }
    std::vector<std::uint64_t>().swap(directed);
    std::vector<char> visited(nv, 0);
    const std::size_t n_triangles_before = triangles.size();
    std::vector<int> loop;
    // Deterministic order: start vertices by id.
    for (std::size_t s0 = 0; s0 < nv; ++s0) {
        if (next[s0] == kNone || visited[s0] != 0) continue;
        const auto s = static_cast<int>(s0);
        loop.clear();
        bool ambiguous = false;
        bool closed = false;
        int v = s;
        while (true) {
            const auto vi = static_cast<std::size_t>(v);
            if (out_count[vi] > 1) ambiguous = true;
            visited[vi] = 1;
            loop.push_back(v);
            if (next[vi] == kNone) break;
            v = next[vi];
            if (v == s) {
                closed = true;
                break;
            }
            if (visited[static_cast<std::size_t>(v)] != 0) break;  // ran into another loop
        }
        if (ambiguous || !closed) {
            ++r.loops_ambiguous;
            continue;
        }
        ++r.holes_found;
        if (static_cast<int>(loop.size()) > max_edges) {
            ++r.holes_too_large;
            continue;
        }
        ++r.holes_filled;
        if (loop.size() == 3) {
            triangles.emplace_back(loop[0], loop[1], loop[2]);
            continue;
        }
        Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
        for (int i : loop) centroid += vertices[static_cast<std::size_t>(i)];
        centroid /= static_cast<float>(loop.size());
        const int c = static_cast<int>(vertices.size());
        vertices.push_back(centroid);
        ++r.vertices_added;
        for (std::size_t i = 0; i < loop.size(); ++i) {
            triangles.emplace_back(loop[i], loop[(i + 1) % loop.size()], c);
        }
    }
    r.triangles_added = static_cast<std::int64_t>(triangles.size() - n_triangles_before);
    return r;
}

MeshResult RunMesh(const fusion::TsdfVolume& volume, const MeshConfig& config) {
    MeshResult result;
    fusion::IsoSurfaceResult iso = volume.ExtractIsoSurface(config.iso_m);
    result.polygons_raw = iso.polygons_raw;
    result.polygons_unobserved = iso.polygons_unobserved;
    result.mesh.vertices = std::move(iso.mesh.vertices);
    result.mesh.triangles = std::move(iso.mesh.triangles);
    if (result.mesh.vertices.empty()) {
        result.message = "empty surface (" + iso.message + ")";
        return result;
    }
    double lo = std::numeric_limits<double>::infinity();
    double hi = -lo;
    for (const Eigen::Vector3f& p : result.mesh.vertices) {
        lo = std::min(lo, static_cast<double>(p.z()));
        hi = std::max(hi, static_cast<double>(p.z()));
    }
    result.min_z_m = lo;
    result.max_z_m = hi;
    if (config.colour_min_z_m != 0.0 || config.colour_max_z_m != 0.0) {
        lo = config.colour_min_z_m;
        hi = config.colour_max_z_m;
    }
    result.area_m2 = MeshArea(result.mesh.vertices, result.mesh.triangles);
    Colourise(result.mesh, lo, hi);
    result.mesh_filled = result.mesh;
    if (config.max_hole_edges > 0) {
        result.holes = FillSmallHoles(
            result.mesh_filled.vertices, result.mesh_filled.triangles, config.max_hole_edges);
        Colourise(result.mesh_filled, lo, hi);
    }
    result.message = std::to_string(result.mesh.vertices.size()) + " vertices, " +
                     std::to_string(result.mesh.triangles.size()) +
                     " triangles; display mesh: " + std::to_string(result.holes.holes_filled) +
                     " holes filled (" + std::to_string(result.holes.triangles_added) +
                     " triangles added), " + std::to_string(result.holes.holes_too_large) +
                     " left open";
    return result;
}

}  // namespace pitmap::proc::mesh
