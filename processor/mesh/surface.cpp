// SPDX-License-Identifier: MIT
#include "processor/mesh/surface.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <vector>

#include <tbb/parallel_sort.h>

namespace pitmap::proc::mesh {

namespace {

std::uint64_t EdgeKey(int a, int b) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
           static_cast<std::uint32_t>(b);
}

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
    // Directed edges of the mesh, sorted (a hash map of them took ~0.5 GB on bejanca's 3 M
    // triangles); a boundary edge a->b has no b->a.
    std::vector<std::uint64_t> directed;
    directed.reserve(triangles.size() * 3);
    for (const Eigen::Vector3i& t : triangles) {
        for (int k = 0; k < 3; ++k) directed.push_back(EdgeKey(t[k], t[(k + 1) % 3]));
    }
    tbb::parallel_sort(directed.begin(), directed.end());
    directed.erase(std::unique(directed.begin(), directed.end()), directed.end());
    // The fill must contain the reverse of each boundary edge: walk b -> a. A start vertex with
    // several boundary edges (non-manifold) keeps the last in edge order; its loop is ambiguous.
    std::unordered_map<int, int> next;  // start vertex -> end vertex (reversed edge)
    std::unordered_map<int, int> out_count;
    for (const std::uint64_t key : directed) {
        const int a = static_cast<int>(key >> 32);
        const int b = static_cast<int>(key & 0xffffffffu);
        if (std::binary_search(directed.begin(), directed.end(), EdgeKey(b, a))) continue;
        next[b] = a;
        ++out_count[b];
    }
    std::vector<std::uint64_t>().swap(directed);
    std::unordered_map<int, char> visited;
    const std::size_t n_triangles_before = triangles.size();
    // Deterministic order: sorted start vertices.
    std::vector<int> starts;
    starts.reserve(next.size());
    for (const auto& kv : next) starts.push_back(kv.first);
    std::sort(starts.begin(), starts.end());
    for (int s : starts) {
        if (visited[s]) continue;
        std::vector<int> loop;
        bool ambiguous = false;
        bool closed = false;
        int v = s;
        while (true) {
            if (out_count[v] > 1) ambiguous = true;
            visited[v] = 1;
            loop.push_back(v);
            auto it = next.find(v);
            if (it == next.end()) break;
            v = it->second;
            if (v == s) {
                closed = true;
                break;
            }
            if (visited[v]) break;  // ran into another loop (non-manifold)
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
