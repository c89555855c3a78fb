// SPDX-License-Identifier: MIT
// pitmap-bench-tsdf: TSDF fusion and meshing of a simulated survey on the TRUE trajectory
// (issue 8). Builds SonarScans from the simulator (tools/sim: PitWorld, TruthTrajectory,
// SonarModel with noise, dropouts and coarse outliers), integrates them, filters by weight,
// meshes, and scores the mesh against the exact terrain:
//   integration_s       wall time of TsdfVolume::Integrate
//   peak_rss_mb         VmHWM of the process after meshing (simulation included)
//   mesh_mean_abs_m     mean |signed distance to the true surface| of the mesh vertices and
//                       triangle centroids (pitmap-eval's mesh_mean_abs_m definition)
//   completeness        share of the insonified true surface (exact ray casts of every
//                       --stride-th beam of every --stride-th ping) within 0.2 m of the mesh
//   integration_cpu_s   process CPU time of Integrate (the machine may be shared: wall time
//                       alone is noisy)
// --min-weight W1,W2,... reports the weight filter's effect: the thresholds are applied in
// ascending order on the same volume, each followed by meshing and scoring (the first gets
// the full report, --out files and --diag).
// --cache FILE keeps the simulated scans and surface samples in FILE (written when missing or
// when its header does not match scenario, --max-pings and --stride), to repeat runs quickly.
// --diag prints where the error is (|error| bins, error by voxel weight) and, with --out,
// writes the vertices off by more than 0.5 m; --beam-width-deg overrides the sonar's width,
// --footprint-neighbours K the pings each side the along-track footprint slope is fitted to
// (TsdfConfig::footprint_neighbour_pings; 0 = off).
// Usage: pitmap-bench-tsdf [--scenario bejanca] [--mode beam|ray] [--threads 2]
//                          [--min-weight W[,W2,...]] [--max-pings N] [--stride 4] [--out DIR]
//                          [--cache FILE] [--diag] [--beam-width-deg D]
//                          [--footprint-neighbours K]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "common/byte_io.hpp"
#include "common/frames.hpp"
#include "common/peak_memory.hpp"
#include "processor/fusion/tsdf.hpp"
#include "processor/fusion/vdb_io.hpp"
#include "processor/mesh/export.hpp"
#include "processor/mesh/surface.hpp"
#include "tools/sim/scenario.hpp"
#include "tools/sim/sonar_model.hpp"
#include "tools/sim/trajectory.hpp"
#include "tools/sim/world.hpp"

namespace {

using namespace pitmap;
namespace fusion = pitmap::proc::fusion;
namespace pmesh = pitmap::proc::mesh;

double Seconds(std::chrono::steady_clock::time_point a) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
}

// Closest distance from p to triangle abc (Ericson, Real-Time Collision Detection, 5.1.5).
double PointTriangleDistance(const Eigen::Vector3d& p,
                             const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c) {
    const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0 && d2 <= 0) return (p - a).norm();
    const Eigen::Vector3d bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0 && d4 <= d3) return (p - b).norm();
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
    const Eigen::Vector3d cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0 && d5 <= d6) return (p - c).norm();
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
    }
    const double denom = 1.0 / (va + vb + vc);
    return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

// Triangles bucketed in a uniform grid (sorted (cell, triangle) pairs) for near queries.
class TriangleGrid {
public:
    TriangleGrid(const pmesh::ColouredMesh& m, double cell_m) : m_(m), cell_(cell_m) {
        for (std::size_t t = 0; t < m.triangles.size(); ++t) {
            Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
            for (int k = 0; k < 3; ++k) {
                const Eigen::Vector3d v =
                    m.vertices[static_cast<std::size_t>(m.triangles[t][k])].cast<double>();
                lo = lo.cwiseMin(v);
                hi = hi.cwiseMax(v);
            }
            const Eigen::Vector3i a = Cell(lo), b = Cell(hi);
            for (int x = a.x(); x <= b.x(); ++x)
                for (int y = a.y(); y <= b.y(); ++y)
                    for (int z = a.z(); z <= b.z(); ++z)
                        pairs_.push_back({Key(x, y, z), static_cast<std::uint32_t>(t)});
        }
        std::sort(pairs_.begin(), pairs_.end());
    }
    // Distance to the nearest triangle if within one cell, else +inf.
    double Distance(const Eigen::Vector3d& p) const {
        const Eigen::Vector3i c = Cell(p);
        double best = std::numeric_limits<double>::infinity();
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    const std::uint64_t key = Key(c.x() + dx, c.y() + dy, c.z() + dz);
                    auto it = std::lower_bound(pairs_.begin(),
                                               pairs_.end(),
                                               std::pair<std::uint64_t, std::uint32_t>{key, 0});
                    for (; it != pairs_.end() && it->first == key; ++it) {
                        const Eigen::Vector3i& t = m_.triangles[it->second];
                        best = std::min(
                            best,
                            PointTriangleDistance(
                                p,
                                m_.vertices[static_cast<std::size_t>(t[0])].cast<double>(),
                                m_.vertices[static_cast<std::size_t>(t[1])].cast<double>(),
                                m_.vertices[static_cast<std::size_t>(t[2])].cast<double>()));
                    }
                }
        return best;
    }

private:
    Eigen::Vector3i Cell(const Eigen::Vector3d& p) const {
        return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / cell_)),
                               static_cast<int>(std::floor(p.y() / cell_)),
                               static_cast<int>(std::floor(p.z() / cell_)));
    }
    static std::uint64_t Key(int x, int y, int z) {
        return (static_cast<std::uint64_t>(x + (1 << 20)) << 42) |
               (static_cast<std::uint64_t>(y + (1 << 20)) << 21) |
               static_cast<std::uint64_t>(z + (1 << 20));
    }
    const pmesh::ColouredMesh& m_;
    double cell_;
    std::vector<std::pair<std::uint64_t, std::uint32_t>> pairs_;
};

struct Options {
    std::string scenario = "bejanca";
    std::string mode = "beam";
    int threads = 2;
    std::vector<float> min_weights;  // ascending; empty = the WeightFilterConfig default
    long max_pings = 0;
    int stride = 4;
    bool diag = false;
    double beam_width_deg = 0;      // 0 = the scenario's sonar beam width
    int footprint_neighbours = -1;  // -1 = TsdfConfig's default
    std::string out;
    std::string cache;
};

double CpuSeconds() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

constexpr std::uint32_t kCacheMagic = 0x50545343;  // "CSTP"
constexpr std::uint32_t kCacheVersion = 1;

std::string CacheKey(const Options& o) {
    return o.scenario + "/" + std::to_string(o.max_pings) + "/" + std::to_string(o.stride);
}

bool SaveCache(const Options& o,
               const std::vector<fusion::SonarScan>& scans,
               const std::vector<Eigen::Vector3d>& samples) {
    std::vector<std::uint8_t> bytes;
    ByteWriter w(bytes);
    w.U32Le(kCacheMagic);
    w.U32Le(kCacheVersion);
    const std::string key = CacheKey(o);
    w.U32Le(static_cast<std::uint32_t>(key.size()));
    w.Bytes(ByteSpan(reinterpret_cast<const std::uint8_t*>(key.data()), key.size()));
    w.U64Le(scans.size());
    for (const fusion::SonarScan& s : scans) {
        w.F64Le(s.gps_time_s);
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 4; ++c) w.F64Le(s.T_world_sonar.matrix()(r, c));
        }
        w.F32Le(s.start_angle_rad);
        w.F32Le(s.angle_increment_rad);
        w.U32Le(static_cast<std::uint32_t>(s.ranges_m.size()));
        for (float r : s.ranges_m) w.F32Le(r);
    }
    w.U64Le(samples.size());
    for (const Eigen::Vector3d& p : samples) {
        for (int k = 0; k < 3; ++k) w.F64Le(p[k]);
    }
    std::ofstream out(o.cache, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    return static_cast<bool>(out);
}

bool LoadCache(const Options& o,
               std::vector<fusion::SonarScan>& scans,
               std::vector<Eigen::Vector3d>& samples) {
    std::ifstream in(o.cache, std::ios::binary);
    if (!in) return false;
    const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                          std::istreambuf_iterator<char>());
    ByteReader r(bytes.data(), bytes.size());
    if (r.U32Le() != kCacheMagic || r.U32Le() != kCacheVersion) return false;
    const std::uint32_t key_size = r.U32Le();
    const ByteSpan key = r.Bytes(key_size);
    if (!r.ok() || std::string(key.begin(), key.end()) != CacheKey(o)) return false;
    scans.resize(r.U64Le());
    for (fusion::SonarScan& s : scans) {
        s.gps_time_s = r.F64Le();
        Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
        for (int row = 0; row < 3; ++row) {
            for (int c = 0; c < 4; ++c) m(row, c) = r.F64Le();
        }
        s.T_world_sonar = Eigen::Isometry3d(m);
        s.start_angle_rad = r.F32Le();
        s.angle_increment_rad = r.F32Le();
        s.ranges_m.resize(r.U32Le());
        for (float& v : s.ranges_m) v = r.F32Le();
        if (!r.ok()) return false;
    }
    samples.resize(r.U64Le());
    for (Eigen::Vector3d& p : samples) {
        for (int k = 0; k < 3; ++k) p[k] = r.F64Le();
    }
    return r.ok() && r.remaining() == 0;
}

bool ParseArgs(int argc, char** argv, Options& o) {
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const bool has = i + 1 < argc;
        if (a == "--scenario" && has)
            o.scenario = argv[++i];
        else if (a == "--mode" && has)
            o.mode = argv[++i];
        else if (a == "--threads" && has)
            o.threads = std::atoi(argv[++i]);
        else if (a == "--min-weight" && has) {
            // A comma-separated list: each threshold is reported (the weight filter's effect).
            std::string list = argv[++i];
            for (std::size_t p = 0; p <= list.size();) {
                const std::size_t q = std::min(list.find(',', p), list.size());
                o.min_weights.push_back(
                    static_cast<float>(std::atof(list.substr(p, q - p).c_str())));
                p = q + 1;
            }
        } else if (a == "--max-pings" && has)
            o.max_pings = std::atol(argv[++i]);
        else if (a == "--stride" && has)
            o.stride = std::max(1, std::atoi(argv[++i]));
        else if (a == "--out" && has)
            o.out = argv[++i];
        else if (a == "--cache" && has)
            o.cache = argv[++i];
        else if (a == "--diag")
            o.diag = true;
        else if (a == "--beam-width-deg" && has)
            o.beam_width_deg = std::atof(argv[++i]);
        else if (a == "--footprint-neighbours" && has)
            o.footprint_neighbours = std::atoi(argv[++i]);
        else {
            std::fprintf(stderr,
                         "usage: pitmap-bench-tsdf [--scenario S] [--mode beam|ray] "
                         "[--threads N] [--min-weight W[,W2,...]] [--max-pings N] "
                         "[--stride K] [--out DIR] [--cache FILE] [--diag] "
                         "[--beam-width-deg D] [--footprint-neighbours K]\n");
            return false;
        }
    }
    if (o.min_weights.empty()) o.min_weights.push_back(fusion::WeightFilterConfig{}.min_weight);
    std::sort(o.min_weights.begin(), o.min_weights.end());
    return o.mode == "beam" || o.mode == "ray";
}

struct Score {
    double mean_abs = 0;
    double rms = 0;
    double p95 = 0;
    double completeness = 0;
    std::size_t covered = 0;
};

// mesh_mean_abs_m over vertices and triangle centroids, and completeness over the samples.
Score ScoreMesh(const pmesh::ColouredMesh& mesh,
                const sim::PitWorld& world,
                const std::vector<Eigen::Vector3d>& samples,
                int threads) {
    Score sc;
    std::vector<double> dist;
    dist.reserve(mesh.vertices.size() + mesh.triangles.size());
    for (const Eigen::Vector3f& v : mesh.vertices) {
        dist.push_back(std::abs(world.SignedDistance(v.cast<double>())));
    }
    for (const Eigen::Vector3i& t : mesh.triangles) {
        const Eigen::Vector3d c = (mesh.vertices[static_cast<std::size_t>(t[0])] +
                                   mesh.vertices[static_cast<std::size_t>(t[1])] +
                                   mesh.vertices[static_cast<std::size_t>(t[2])])
                                      .cast<double>() /
                                  3.0;
        dist.push_back(std::abs(world.SignedDistance(c)));
    }
    if (!dist.empty()) {
        for (double d : dist) {
            sc.mean_abs += d;
            sc.rms += d * d;
        }
        sc.mean_abs /= static_cast<double>(dist.size());
        sc.rms = std::sqrt(sc.rms / static_cast<double>(dist.size()));
        const std::size_t k = static_cast<std::size_t>(0.95 * static_cast<double>(dist.size()));
        std::nth_element(dist.begin(), dist.begin() + static_cast<std::ptrdiff_t>(k), dist.end());
        sc.p95 = dist[k];
    }
    const TriangleGrid grid(mesh, 0.25);
    std::vector<char> hit(samples.size(), 0);
    std::atomic<std::size_t> next{0};
    auto work = [&] {
        for (std::size_t i = next++; i < samples.size(); i = next++) {
            hit[i] = grid.Distance(samples[i]) <= 0.2 ? 1 : 0;
        }
    };
    std::vector<std::thread> pool;
    for (int k = 1; k < std::max(1, threads); ++k) pool.emplace_back(work);
    work();
    for (auto& th : pool) th.join();
    for (char h : hit) sc.covered += static_cast<std::size_t>(h);
    sc.completeness = samples.empty()
                          ? 0.0
                          : static_cast<double>(sc.covered) / static_cast<double>(samples.size());
    return sc;
}

}  // namespace

int main(int argc, char** argv) {
    Options opt;
    if (!ParseArgs(argc, argv, opt)) return 2;
    auto sc_or = sim::BuiltinScenario(opt.scenario);
    if (!sc_or) {
        std::fprintf(stderr, "pitmap-bench-tsdf: %s\n", sc_or.error().message.c_str());
        return 2;
    }
    const sim::ScenarioConfig sc = *sc_or;
    const sim::PitWorld world(sc.pit, sc.seed);
    auto track = sim::SurveyTrack::Plan(sc);
    if (!track) {
        std::fprintf(stderr, "pitmap-bench-tsdf: %s\n", track.error().message.c_str());
        return 2;
    }
    const sim::TruthTrajectory truth(sc, *track);
    const sim::SonarModel sonar(sc.sonar, world, sc.seed);
    const Eigen::Matrix3d R_vehicle_sonar =
        frames::RotationNedFromRpy(frames::DegToRad(sc.boresight_deg[0]),
                                   frames::DegToRad(sc.boresight_deg[1]),
                                   frames::DegToRad(sc.boresight_deg[2]));
    const Pose T_vehicle_sonar =
        MakePose(R_vehicle_sonar,
                 Eigen::Vector3d(
                     sc.lever_arms.sonar_m[0], sc.lever_arms.sonar_m[1], sc.lever_arms.sonar_m[2]));
    long n_pings = static_cast<long>(std::floor(truth.duration_s() * sc.sonar.ping_rate_hz + 1e-9));
    if (opt.max_pings > 0) n_pings = std::min(n_pings, opt.max_pings);

    // 1. Simulate the pings (parallel, deterministic per ping), or read them from the cache.
    const auto t_sim = std::chrono::steady_clock::now();
    std::vector<fusion::SonarScan> scans;
    std::vector<Eigen::Vector3d> samples;  // insonified true surface
    const bool cached = !opt.cache.empty() && LoadCache(opt, scans, samples);
    if (!cached) {
        scans.resize(static_cast<std::size_t>(n_pings));
        const float start = static_cast<float>(frames::DegToRad(sonar.BeamAngleDeg(0)));
        const float inc =
            static_cast<float>(frames::DegToRad(sonar.BeamAngleDeg(1) - sonar.BeamAngleDeg(0)));
        const double res_m = sc.sonar.range_resolution_mm * 1e-3;
        std::vector<std::vector<Eigen::Vector3d>> samples_per(static_cast<std::size_t>(n_pings));
        {
            std::atomic<long> next{0};
            auto work = [&] {
                for (long i = next++; i < n_pings; i = next++) {
                    const double t = static_cast<double>(i) / sc.sonar.ping_rate_hz;
                    const Pose T = truth.PoseAt(t) * T_vehicle_sonar;
                    const sim::SimPing ping = sonar.Ping(T, i);
                    fusion::SonarScan& s = scans[static_cast<std::size_t>(i)];
                    s.gps_time_s = t;
                    s.T_world_sonar = T;
                    s.start_angle_rad = start;
                    s.angle_increment_rad = inc;
                    s.ranges_m.resize(ping.range_counts.size());
                    for (std::size_t b = 0; b < ping.range_counts.size(); ++b) {
                        s.ranges_m[b] = static_cast<float>(ping.range_counts[b] * res_m);
                    }
                    if (i % opt.stride != 0) continue;
                    auto& out = samples_per[static_cast<std::size_t>(i)];
                    for (std::size_t b = 0; b < ping.range_counts.size();
                         b += static_cast<std::size_t>(opt.stride)) {
                        const double th = frames::DegToRad(sonar.BeamAngleDeg(static_cast<int>(b)));
                        const Eigen::Vector3d dir =
                            T.linear() * Eigen::Vector3d(0.0, std::sin(th), std::cos(th));
                        const auto r = world.RayCast(T.translation(), dir, sc.sonar.max_range_m);
                        if (r) out.push_back(T.translation() + *r * dir);
                    }
                }
            };
            std::vector<std::thread> pool;
            for (int k = 1; k < std::max(1, opt.threads); ++k) pool.emplace_back(work);
            work();
            for (auto& th : pool) th.join();
        }
        for (auto& v : samples_per) samples.insert(samples.end(), v.begin(), v.end());
        samples_per.clear();
        samples_per.shrink_to_fit();
        if (!opt.cache.empty() && !SaveCache(opt, scans, samples)) {
            std::fprintf(
                stderr, "pitmap-bench-tsdf: %s: cannot write the cache\n", opt.cache.c_str());
        }
    }
    n_pings = static_cast<long>(scans.size());
    const double sim_s = Seconds(t_sim);

    // 2. Fuse.
    fusion::TsdfConfig config;
    config.sensor_model =
        opt.mode == "beam" ? fusion::SensorModel::kBeamWidth : fusion::SensorModel::kRay;
    config.beam_width_rad =
        frames::DegToRad(opt.beam_width_deg > 0 ? opt.beam_width_deg : sc.sonar.beam_width_deg);
    config.num_threads = opt.threads;
    if (opt.footprint_neighbours >= 0) config.footprint_neighbour_pings = opt.footprint_neighbours;
    if (const auto problems = config.Validate(); !problems.empty()) {
        for (const auto& p : problems) std::fprintf(stderr, "pitmap-bench-tsdf: %s\n", p.c_str());
        return 2;
    }
    fusion::TsdfVolume volume(config);
    const double cpu0 = CpuSeconds();
    const fusion::IntegrateResult ir = volume.Integrate(scans);
    const double integration_cpu_s = CpuSeconds() - cpu0;
    const fusion::VolumeStats stats_before = volume.Stats();
    const fusion::WeightHistogram hist = volume.ComputeWeightHistogram();

    std::printf("scenario %s, mode %s, threads %d, pings %ld, beams used %lld\n",
                opt.scenario.c_str(),
                opt.mode.c_str(),
                opt.threads,
                n_pings,
                static_cast<long long>(ir.beams_used));
    std::printf("  simulate_s        %.1f%s\n", sim_s, cached ? "   (read from the cache)" : "");
    std::printf(
        "  integration_s     %.2f   (cpu %.2f s; %lld voxel updates; %lld beams "
        "outvoted by their footprint)\n",
        ir.elapsed_s,
        integration_cpu_s,
        static_cast<long long>(ir.voxel_updates),
        static_cast<long long>(ir.beams_inconsistent));
    std::printf("  active_voxels     %lld   (grids %.0f MB)\n",
                static_cast<long long>(stats_before.active_voxels),
                static_cast<double>(stats_before.memory_bytes) / 1048576.0);
    std::printf("  weight histogram  (%% of active voxels, weight 0..%d):",
                static_cast<int>(hist.counts.size()) - 1);
    for (std::int64_t c : hist.counts) {
        std::printf(" %.1f",
                    hist.total > 0
                        ? 100.0 * static_cast<double>(c) / static_cast<double>(hist.total)
                        : 0.0);
    }
    std::printf("\n");

    // 3. For each threshold (ascending; the filter is applied on top of the previous one):
    // filter, mesh, score. The first threshold gets the full report and the files.
    for (std::size_t ti = 0; ti < opt.min_weights.size(); ++ti) {
        const float min_weight = opt.min_weights[ti];
        fusion::WeightFilterConfig wf;
        wf.min_weight = min_weight;
        const auto t_filter = std::chrono::steady_clock::now();
        const fusion::WeightFilterResult fr = volume.FilterByWeight(wf);
        const double filter_s = Seconds(t_filter);
        const std::int64_t removed = stats_before.active_voxels - fr.voxels_after;
        const auto t_mesh = std::chrono::steady_clock::now();
        const pmesh::MeshResult mr = pmesh::RunMesh(volume, pmesh::MeshConfig{});
        const double mesh_s = Seconds(t_mesh);
        const double peak_mb = PeakRssMb();
        const Score sc_m = ScoreMesh(mr.mesh, world, samples, opt.threads);
        if (ti > 0) {
            std::printf(
                "  min_weight %-5.1f removed %5.2f %% of the voxels; %zu vertices; mean "
                "%.4f m (rms %.4f, p95 %.4f); completeness %.4f\n",
                static_cast<double>(min_weight),
                100.0 * static_cast<double>(removed) /
                    static_cast<double>(std::max<std::int64_t>(1, stats_before.active_voxels)),
                mr.mesh.vertices.size(),
                sc_m.mean_abs,
                sc_m.rms,
                sc_m.p95,
                sc_m.completeness);
            continue;
        }
        std::printf("  weight_filter     min %.1f: removed %lld of %lld (%.2f %%) in %.2f s\n",
                    static_cast<double>(min_weight),
                    static_cast<long long>(fr.voxels_removed),
                    static_cast<long long>(fr.voxels_before),
                    fr.voxels_before > 0 ? 100.0 * static_cast<double>(fr.voxels_removed) /
                                               static_cast<double>(fr.voxels_before)
                                         : 0.0,
                    filter_s);
        std::printf(
            "  mesh_s            %.2f   (%zu vertices, %zu triangles, %lld polygons "
            "dropped at unobserved cells; filled %lld holes)\n",
            mesh_s,
            mr.mesh.vertices.size(),
            mr.mesh.triangles.size(),
            static_cast<long long>(mr.polygons_unobserved),
            static_cast<long long>(mr.holes.holes_filled));
        std::printf("  peak_rss_mb       %.0f\n", peak_mb);
        std::printf(
            "  mesh_mean_abs_m   %.4f   (rms %.4f, p95 %.4f)\n", sc_m.mean_abs, sc_m.rms, sc_m.p95);
        std::printf(
            "  completeness      %.4f   (%zu of %zu insonified surface samples within "
            "0.2 m)\n",
            sc_m.completeness,
            sc_m.covered,
            samples.size());
        if (!opt.out.empty()) {
            std::filesystem::create_directories(opt.out);
            const Geodetic origin{
                sc.origin_latitude_deg, sc.origin_longitude_deg, sc.origin_height_m};
            const std::string d = opt.out + "/";
            for (const Status& s : {pmesh::WritePly(mr.mesh, d + "mesh.ply", origin),
                                    pmesh::WriteObj(mr.mesh, d + "mesh.obj", origin),
                                    pmesh::WriteGlb(mr.mesh, d + "mesh.glb", origin),
                                    pmesh::WritePly(mr.mesh_filled, d + "mesh_filled.ply", origin),
                                    fusion::WriteVdb(volume, d + "tsdf.vdb")}) {
                if (!s) std::fprintf(stderr, "pitmap-bench-tsdf: %s\n", s.error().message.c_str());
            }
        }
        if (opt.diag) {
            // Where the error is: vertex |distance| by the weight of their voxel and by size.
            constexpr int kBins = 6;
            const double lim[kBins] = {0.05, 0.1, 0.2, 0.5, 1.0, 1e300};
            std::int64_t by_err[kBins] = {};
            double sum_by_err[kBins] = {};
            std::vector<std::int64_t> n_w(22, 0);
            std::vector<double> e_w(22, 0.0);
            std::vector<std::int64_t> bad_w(22, 0);
            std::int64_t bad_above = 0, bad_below = 0;
            std::int64_t bad_z[10] = {};
            std::FILE* bad_csv = opt.out.empty()
                                     ? nullptr
                                     : std::fopen((opt.out + "/bad_vertices.txt").c_str(), "w");
            for (const Eigen::Vector3f& v : mr.mesh.vertices) {
                const double e = std::abs(world.SignedDistance(v.cast<double>()));
                int k = 0;
                while (e > lim[k]) ++k;
                ++by_err[k];
                sum_by_err[k] += e;
                const float w = volume.WeightAt(v.cast<double>());
                const std::size_t wb = std::min<std::size_t>(21, static_cast<std::size_t>(w));
                ++n_w[wb];
                e_w[wb] += e;
                if (e > 0.2) ++bad_w[wb];
                if (e > 0.5) {
                    const double sd = world.SignedDistance(v.cast<double>());
                    if (bad_csv) {
                        std::fprintf(bad_csv,
                                     "%.2f %.2f %.2f %.3f %.0f %.3f %.3f\n",
                                     v.x(),
                                     v.y(),
                                     v.z(),
                                     sd,
                                     static_cast<double>(w),
                                     world.Height(v.x(), v.y()),
                                     static_cast<double>(volume.DistanceAt(v.cast<double>())));
                    }
                    ++(sd > 0 ? bad_above : bad_below);
                    bad_z[std::min<std::size_t>(9, static_cast<std::size_t>(-v.z() / 3.0))]++;
                }
            }
            if (bad_csv) std::fclose(bad_csv);
            std::printf(
                "  vertices off by > 0.5 m: %lld above the true surface, %lld below; by depth "
                "(3 m bins):",
                static_cast<long long>(bad_above),
                static_cast<long long>(bad_below));
            for (std::int64_t b : bad_z) std::printf(" %lld", static_cast<long long>(b));
            std::printf("\n");
            const double nv = static_cast<double>(mr.mesh.vertices.size());
            std::printf("  vertex |error| bins (share, contribution to the mean):\n");
            for (int k = 0; k < kBins; ++k) {
                std::printf("    <= %-6.2f %6.2f %%  %.4f m\n",
                            lim[k] > 1e9 ? 99.0 : lim[k],
                            100.0 * static_cast<double>(by_err[k]) / nv,
                            sum_by_err[k] / nv);
            }
            std::printf(
                "  vertices by the weight of their nearest voxel (count, mean |error|, > 0.2 "
                "m):\n");
            for (std::size_t w = 0; w < n_w.size(); ++w) {
                if (n_w[w] == 0) continue;
                std::printf("    w %2zu  %9lld  %.4f  %lld\n",
                            w,
                            static_cast<long long>(n_w[w]),
                            e_w[w] / static_cast<double>(n_w[w]),
                            static_cast<long long>(bad_w[w]));
            }
        }
        if (opt.min_weights.size() > 1) {
            std::printf("  weight filter effect (thresholds applied in turn):\n");
        }
    }
    return 0;
}
