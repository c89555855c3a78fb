// SPDX-License-Identifier: MIT
// pitmap edit's lasso over every sounding of a bejanca-sized survey (issue 35: a lasso of
// 100 k soundings must answer in < 1 s). 5.9 M synthetic soundings (float32, the session's
// frame: a 2.4 km x 2.4 km pit floor 20-80 m deep with 1 cm noise) seen from above through a
// perspective view-projection matrix as three.js sends it; the lasso is a 64-vertex circle in
// NDC sized to hold ~100 k of them. Measured: SelectInPolygon (projection and point in polygon,
// TBB) alone, and with what EditSession::Apply adds per edit (the status test per selected
// sounding and survey::RunsOf of the changed ones); counters say how many were selected.
// Threads: BM_Lasso/threads (0 = all cores).
//
// Usage: pitmap-bench-edit_select [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "processor/edit/selection.hpp"
#include "processor/survey/edit_log.hpp"

namespace {

using pitmap::proc::edit::NdcPoint;
using pitmap::proc::edit::SelectionQuery;

constexpr std::size_t kSoundings = 5'900'000;
constexpr std::size_t kBeams = 256;

struct World {
    std::vector<float> xyz;
    pitmap::proc::survey::PingSeries pings;  // kSoundings / kBeams pings of kBeams beams
    SelectionQuery query;
};

const World& TheWorld() {
    static const World w = [] {
        World out;
        std::mt19937 rng(3);
        std::uniform_real_distribution<float> u(-1200, 1200);
        std::normal_distribution<float> noise(0, 0.01f);
        out.xyz.resize(3 * kSoundings);
        for (std::size_t i = 0; i < kSoundings; ++i) {
            const float x = u(rng), y = u(rng);
            out.xyz[3 * i] = x;
            out.xyz[3 * i + 1] = y;
            out.xyz[3 * i + 2] =
                -50 + 30 * std::sin(x / 300.0f) * std::cos(y / 400.0f) + noise(rng);
        }
        std::uint32_t offset = 0;
        for (std::size_t k = 0; k < kSoundings / kBeams + 1; ++k) {
            pitmap::proc::survey::PingHeader h;
            h.ping_number = static_cast<std::int64_t>(k);
            h.beam_offset = offset;
            h.num_beams = static_cast<std::uint16_t>(std::min(kBeams, kSoundings - offset));
            offset += h.num_beams;
            out.pings.pings.push_back(h);
        }
        out.pings.range_counts.assign(kSoundings, 1);
        // A camera 3 km above the centre looking down (up = north), 50 deg field of view,
        // square viewport: three.js's makePerspective times the inverse camera matrix.
        const double f = 1 / std::tan(25.0 * M_PI / 180), n = 10, fa = 10000, hgt = 3000;
        const double a = -(fa + n) / (fa - n), b = -2 * fa * n / (fa - n);
        // View: x -> x, y -> y, z -> z - hgt (the camera's -z is down).
        out.query.view_projection = {f, 0, 0, 0, 0, f, 0, 0, 0, 0, a, -1, 0, 0, a * -hgt + b, hgt};
        // ~100 k of 5.9 M: the circle's share of the view's area in NDC.
        const double view_half_m = hgt / f;  // at z = 0
        const double share =
            100'000.0 / kSoundings * (2400.0 * 2400.0) / (4 * view_half_m * view_half_m);
        const double r = std::sqrt(4 * share / M_PI);
        for (int k = 0; k < 64; ++k) {
            const double t = 2 * M_PI * k / 64;
            out.query.polygon.push_back({0.1 + r * std::cos(t), -0.05 + r * std::sin(t)});
        }
        return out;
    }();
    return w;
}

void BM_Lasso(benchmark::State& state) {
    const World& w = TheWorld();
    std::size_t selected = 0;
    for (auto _ : state) {
        const auto idx = pitmap::proc::edit::SelectInPolygon(
            w.xyz.data(), kSoundings, w.query, {}, static_cast<int>(state.range(0)));
        selected = idx.size();
        benchmark::DoNotOptimize(idx.data());
    }
    state.counters["selected"] = static_cast<double>(selected);
    state.counters["soundings"] = static_cast<double>(kSoundings);
}
BENCHMARK(BM_Lasso)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();

// The lasso plus what an edit adds: the status test of each selected sounding (every other one
// accepted here) and the runs of the changed ones.
void BM_LassoEdit(benchmark::State& state) {
    const World& w = TheWorld();
    std::size_t runs = 0;
    for (auto _ : state) {
        const auto idx =
            pitmap::proc::edit::SelectInPolygon(w.xyz.data(), kSoundings, w.query, {}, 0);
        std::vector<std::uint32_t> change;
        for (const std::uint32_t i : idx) {
            if (i % 2 == 0) change.push_back(i);
        }
        runs = pitmap::proc::survey::RunsOf(w.pings, std::move(change)).size();
        benchmark::DoNotOptimize(runs);
    }
    state.counters["runs"] = static_cast<double>(runs);
}
BENCHMARK(BM_LassoEdit)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
