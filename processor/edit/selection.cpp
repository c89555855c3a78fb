// SPDX-License-Identifier: MIT
#include "processor/edit/selection.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>

namespace pitmap::proc::edit {

std::vector<std::string> SelectionQuery::Validate() const {
    std::vector<std::string> p;
    if (polygon.size() < 3) p.push_back("selection: the polygon needs at least 3 vertices");
    if (polygon.size() > kMaxPolygonVertices) {
        p.push_back("selection: the polygon has " + std::to_string(polygon.size()) +
                    " vertices (at most " + std::to_string(kMaxPolygonVertices) + ")");
    }
    for (const NdcPoint& v : polygon) {
        if (!std::isfinite(v.x) || !std::isfinite(v.y)) {
            p.push_back("selection: a polygon vertex is not a finite number");
            break;
        }
    }
    for (const double e : view_projection) {
        if (!std::isfinite(e)) {
            p.push_back("selection: the view-projection matrix has a non-finite element");
            break;
        }
    }
    return p;
}

std::vector<NdcPoint> BoxPolygon(NdcPoint a, NdcPoint b) {
    const double x0 = std::min(a.x, b.x), x1 = std::max(a.x, b.x);
    const double y0 = std::min(a.y, b.y), y1 = std::max(a.y, b.y);
    return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

bool InsidePolygon(const std::vector<NdcPoint>& polygon, double x, double y) {
    // Crossing number: a ray from (x, y) towards +x crosses edge (a, b) when y lies in
    // [min(ya, yb), max(ya, yb)) and the edge's x at y is greater than x. The half-open
    // interval counts a vertex once and leaves horizontal edges out.
    bool inside = false;
    const std::size_t n = polygon.size();
    for (std::size_t i = 0, k = n - 1; i < n; k = i++) {
        const NdcPoint& a = polygon[i];
        const NdcPoint& b = polygon[k];
        if ((a.y > y) != (b.y > y)) {
            const double x_at = a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y);
            if (x < x_at) inside = !inside;
        }
    }
    return inside;
}

Projected Project(const std::array<double, 16>& m, double x, double y, double z) {
    // Column-major: element (row r, column c) is m[4 c + r].
    const double cx = m[0] * x + m[4] * y + m[8] * z + m[12];
    const double cy = m[1] * x + m[5] * y + m[9] * z + m[13];
    const double cz = m[2] * x + m[6] * y + m[10] * z + m[14];
    const double cw = m[3] * x + m[7] * y + m[11] * z + m[15];
    Projected p;
    if (!(cw > 0) || !std::isfinite(cw)) return p;
    p.x = cx / cw;
    p.y = cy / cw;
    p.z = cz / cw;
    p.in_view = std::isfinite(p.x) && std::isfinite(p.y) && p.z >= -1 && p.z <= 1;
    return p;
}

std::vector<std::uint32_t> SelectInPolygon(const float* xyz,
                                           std::size_t n,
                                           const SelectionQuery& query,
                                           const std::function<bool(std::size_t)>& eligible,
                                           int num_threads) {
    double x0 = query.polygon[0].x, x1 = x0, y0 = query.polygon[0].y, y1 = y0;
    for (const NdcPoint& v : query.polygon) {
        x0 = std::min(x0, v.x);
        x1 = std::max(x1, v.x);
        y0 = std::min(y0, v.y);
        y1 = std::max(y1, v.y);
    }
    // Fixed blocks, each collecting its own hits; concatenated in block order, the result is
    // sorted and independent of the thread count.
    constexpr std::size_t kBlock = 1 << 16;
    const std::size_t num_blocks = (n + kBlock - 1) / kBlock;
    std::vector<std::vector<std::uint32_t>> hits(num_blocks);
    const auto run = [&] {
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, num_blocks),
            [&](const tbb::blocked_range<std::size_t>& r) {
                for (std::size_t b = r.begin(); b != r.end(); ++b) {
                    const std::size_t end = std::min(n, (b + 1) * kBlock);
                    for (std::size_t i = b * kBlock; i < end; ++i) {
                        const Projected p = Project(query.view_projection,
                                                    double{xyz[3 * i]},
                                                    double{xyz[3 * i + 1]},
                                                    double{xyz[3 * i + 2]});
                        if (!p.in_view || p.x < x0 || p.x > x1 || p.y < y0 || p.y > y1) continue;
                        if (!InsidePolygon(query.polygon, p.x, p.y)) continue;
                        if (eligible && !eligible(i)) continue;
                        hits[b].push_back(static_cast<std::uint32_t>(i));
                    }
                }
            });
    };
    if (num_threads > 0) {
        tbb::task_arena arena(num_threads);
        arena.execute(run);
    } else {
        run();
    }
    std::size_t total = 0;
    for (const auto& h : hits) total += h.size();
    std::vector<std::uint32_t> out;
    out.reserve(total);
    for (const auto& h : hits) out.insert(out.end(), h.begin(), h.end());
    return out;
}

}  // namespace pitmap::proc::edit
