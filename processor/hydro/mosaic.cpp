// SPDX-License-Identifier: MIT
#include "processor/hydro/mosaic.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "common/result.hpp"

namespace pitmap::proc::hydro {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr double kPi = 3.14159265358979323846;

double Percentile(std::vector<float> v, double q) {
    if (v.empty()) return 0;
    const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k];
}

int NumBins(double bin_deg, double max_incidence_deg) {
    return std::max(1, static_cast<int>(std::ceil(max_incidence_deg / bin_deg)));
}

}  // namespace

const char* ToString(AngularCorrection a) {
    switch (a) {
        case AngularCorrection::kNone:
            return "none";
        case AngularCorrection::kLambert:
            return "lambert";
        case AngularCorrection::kEmpirical:
            return "empirical";
    }
    return "?";
}

std::vector<std::string> MosaicConfig::Validate() const {
    std::vector<std::string> p;
    if (!(spreading_db_per_decade >= 0 && spreading_db_per_decade <= 80))
        p.push_back("mosaic.spreading_db_per_decade must be within 0..80");
    if (!(absorption_db_per_m >= 0 && absorption_db_per_m <= 1))
        p.push_back("mosaic.absorption_db_per_m must be within 0..1");
    if (!(max_incidence_deg > 10 && max_incidence_deg <= 89))
        p.push_back("mosaic.max_incidence_deg must be within 10..89");
    if (!(reference_angle_deg >= 0 && reference_angle_deg < max_incidence_deg))
        p.push_back("mosaic.reference_angle_deg must be within 0..max_incidence_deg");
    if (!(angle_bin_deg >= 0.1 && angle_bin_deg <= 10))
        p.push_back("mosaic.angle_bin_deg must be within 0.1..10");
    if (min_bin_soundings < 1) p.push_back("mosaic.min_bin_soundings must be >= 1");
    if (empirical_iterations < 0 || empirical_iterations > 20)
        p.push_back("mosaic.empirical_iterations must be within 0..20");
    return p;
}

double AngularResponse::At(double incidence_deg) const {
    if (level_db.empty()) return 0;
    // Bin k's value sits at its centre (k + 0.5) * bin_deg.
    const double u = incidence_deg / bin_deg - 0.5;
    if (u <= 0) return level_db.front();
    const auto last = static_cast<double>(level_db.size() - 1);
    if (u >= last) return level_db.back();
    const auto k = static_cast<std::size_t>(u);
    const double f = u - static_cast<double>(k);
    return (1 - f) * level_db[k] + f * level_db[k + 1];
}

double IntensityDb(std::uint16_t intensity) {
    return 20.0 * std::log10(std::max<double>(1.0, intensity));
}

double RangeLossDb(double range_m, const MosaicConfig& c) {
    return c.spreading_db_per_decade * std::log10(range_m) + 2.0 * c.absorption_db_per_m * range_m;
}

double IncidenceDeg(const Eigen::Vector3d& beam_dir, const Eigen::Vector3d& normal_up) {
    const double c = -beam_dir.dot(normal_up);
    if (!(c > 0)) return 90.0;
    return std::acos(std::min(1.0, c)) * 180.0 / kPi;
}

Eigen::Vector3d DemNormal(const MosaicGrid& g, int i, int j) {
    const std::vector<float>& z = *g.elevation_m;
    const auto at = [&](int a, int b) -> double {
        if (a < 0 || b < 0 || a >= g.nx || b >= g.ny) return std::nan("");
        return z[static_cast<std::size_t>(b) * static_cast<std::size_t>(g.nx) +
                 static_cast<std::size_t>(a)];
    };
    // Slope along one axis: central where both neighbours are there, else one-sided.
    const auto slope = [&](double lo, double mid, double hi) {
        if (std::isfinite(lo) && std::isfinite(hi)) return (hi - lo) / (2 * g.resolution_m);
        if (std::isfinite(mid) && std::isfinite(hi)) return (hi - mid) / g.resolution_m;
        if (std::isfinite(mid) && std::isfinite(lo)) return (mid - lo) / g.resolution_m;
        return 0.0;
    };
    const double c = at(i, j);
    const double dx = slope(at(i - 1, j), c, at(i + 1, j));
    const double dy = slope(at(i, j - 1), c, at(i, j + 1));
    return Eigen::Vector3d(-dx, -dy, 1.0).normalized();
}

AngularResponse LambertResponse(double bin_deg, double max_incidence_deg) {
    AngularResponse r;
    r.bin_deg = bin_deg;
    const int n = NumBins(bin_deg, max_incidence_deg);
    r.level_db.resize(static_cast<std::size_t>(n));
    r.counts.assign(static_cast<std::size_t>(n), 0);
    for (int k = 0; k < n; ++k) {
        const double t = std::min(89.0, (k + 0.5) * bin_deg) * kPi / 180.0;
        r.level_db[static_cast<std::size_t>(k)] = 20.0 * std::log10(std::cos(t));
    }
    return r;
}

AngularResponse EstimateAngularResponse(const std::vector<float>& level_db,
                                        const std::vector<float>& incidence_deg,
                                        const MosaicConfig& c) {
    AngularResponse r;
    r.bin_deg = c.angle_bin_deg;
    const int n = NumBins(c.angle_bin_deg, c.max_incidence_deg);
    std::vector<double> sum(static_cast<std::size_t>(n), 0.0);
    r.counts.assign(static_cast<std::size_t>(n), 0);
    for (std::size_t j = 0; j < level_db.size(); ++j) {
        const double t = incidence_deg[j];
        if (!(t >= 0 && t <= c.max_incidence_deg) || !std::isfinite(level_db[j])) continue;
        const int k = std::min(n - 1, static_cast<int>(t / c.angle_bin_deg));
        sum[static_cast<std::size_t>(k)] += level_db[j];
        ++r.counts[static_cast<std::size_t>(k)];
    }
    r.level_db.assign(static_cast<std::size_t>(n), std::nan(""));
    std::vector<int> good;
    for (int k = 0; k < n; ++k) {
        const auto kk = static_cast<std::size_t>(k);
        if (r.counts[kk] >= c.min_bin_soundings) {
            r.level_db[kk] = sum[kk] / static_cast<double>(r.counts[kk]);
            good.push_back(k);
        }
    }
    if (good.empty()) {
        r.level_db.assign(static_cast<std::size_t>(n), 0.0);
        return r;
    }
    // Thin bins: linear between the nearest good ones, constant beyond the end ones.
    for (int k = 0; k < n; ++k) {
        const auto kk = static_cast<std::size_t>(k);
        if (std::isfinite(r.level_db[kk])) continue;
        const auto hi = std::lower_bound(good.begin(), good.end(), k);
        if (hi == good.begin()) {
            r.level_db[kk] = r.level_db[static_cast<std::size_t>(good.front())];
        } else if (hi == good.end()) {
            r.level_db[kk] = r.level_db[static_cast<std::size_t>(good.back())];
        } else {
            const int a = *(hi - 1), b = *hi;
            const double f = static_cast<double>(k - a) / static_cast<double>(b - a);
            r.level_db[kk] = (1 - f) * r.level_db[static_cast<std::size_t>(a)] +
                             f * r.level_db[static_cast<std::size_t>(b)];
        }
    }
    return r;
}

AngularResponse RefineAngularResponse(const AngularResponse& response,
                                      const std::vector<float>& level_db,
                                      const std::vector<float>& incidence_deg,
                                      const std::vector<std::uint32_t>& node,
                                      std::size_t num_nodes,
                                      const MosaicConfig& c) {
    std::vector<double> sum(num_nodes, 0.0);
    std::vector<std::uint32_t> cnt(num_nodes, 0);
    for (std::size_t j = 0; j < level_db.size(); ++j) {
        if (node[j] >= num_nodes || !std::isfinite(level_db[j])) continue;
        sum[node[j]] += level_db[j] - response.At(incidence_deg[j]);
        ++cnt[node[j]];
    }
    std::vector<float> residual(level_db.size(), kNaN);
    for (std::size_t j = 0; j < level_db.size(); ++j) {
        if (node[j] >= num_nodes || !std::isfinite(level_db[j])) continue;
        residual[j] = static_cast<float>(level_db[j] - sum[node[j]] / cnt[node[j]]);
    }
    return EstimateAngularResponse(residual, incidence_deg, c);
}

namespace {

constexpr std::uint32_t kNoNode = std::numeric_limits<std::uint32_t>::max();

// Every sounding's node, range-corrected level and incidence on the DEM (kNoNode and NaN where
// unusable), and the uncorrected levels' sum per node.
struct LevelledSoundings {
    std::vector<std::uint32_t> node;
    std::vector<float> level_db;
    std::vector<float> incidence_deg;
    std::vector<double> uncorrected_sum_db;  // per node
};

// The first pass, a block of the soundings at a time (in order): the soundings with an
// intensity (neither none nor saturated) on a node of the grid, at an incidence up to
// max_incidence_deg, appended to `out`, the others counted by reason in `r`. The DEM's normal
// is computed once per node that a sounding falls on (`normals`, `have_normal`).
void LevelSoundings(const MosaicSoundings& s,
                    const MosaicGrid& g,
                    const MosaicConfig& c,
                    std::vector<Eigen::Vector3d>& normals,
                    std::vector<char>& have_normal,
                    LevelledSoundings& out,
                    MosaicResult& r) {
    const std::size_t n = s.size();
    const std::size_t first = out.node.size();
    out.node.resize(first + n, kNoNode);
    out.level_db.resize(first + n, kNaN);
    out.incidence_deg.resize(first + n, kNaN);
    for (std::size_t j = 0; j < n; ++j) {
        const std::uint16_t intensity = s.intensity[j];
        if (intensity == 0) {
            ++r.no_intensity;
            continue;
        }
        if (intensity == 65535) {
            ++r.saturated;
            continue;
        }
        const long col = std::lround((s.x[j] - g.x0) / g.resolution_m);
        const long row = std::lround((s.y[j] - g.y0) / g.resolution_m);
        if (col < 0 || row < 0 || col >= g.nx || row >= g.ny || !(s.range_m[j] > 0)) {
            ++r.outside_grid;
            continue;
        }
        const std::size_t cell = static_cast<std::size_t>(row) * static_cast<std::size_t>(g.nx) +
                                 static_cast<std::size_t>(col);
        if (!have_normal[cell]) {
            normals[cell] = DemNormal(g, static_cast<int>(col), static_cast<int>(row));
            have_normal[cell] = 1;
        }
        const double incidence =
            IncidenceDeg(s.beam_dir[j].cast<double>().normalized(), normals[cell]);
        if (incidence > c.max_incidence_deg) {
            ++r.beyond_incidence;
            continue;
        }
        out.node[first + j] = static_cast<std::uint32_t>(cell);
        const float raw = static_cast<float>(IntensityDb(intensity));
        out.uncorrected_sum_db[cell] += raw;
        out.level_db[first + j] = static_cast<float>(raw + RangeLossDb(s.range_m[j], c));
        out.incidence_deg[first + j] = static_cast<float>(incidence);
    }
}

// The angular response the levels are corrected by: the survey's own (estimated, then refined
// against the nodes' means), Lambert's, or none (zero in every bin).
AngularResponse ChosenAngularResponse(const LevelledSoundings& levelled,
                                      std::size_t cells,
                                      const MosaicConfig& c) {
    AngularResponse response;
    switch (c.angular) {
        case AngularCorrection::kEmpirical:
            response = EstimateAngularResponse(levelled.level_db, levelled.incidence_deg, c);
            for (int it = 0; it < c.empirical_iterations; ++it) {
                response = RefineAngularResponse(
                    response, levelled.level_db, levelled.incidence_deg, levelled.node, cells, c);
            }
            break;
        case AngularCorrection::kLambert:
            response = LambertResponse(c.angle_bin_deg, c.max_incidence_deg);
            break;
        case AngularCorrection::kNone: {
            response.bin_deg = c.angle_bin_deg;
            const int bins = NumBins(c.angle_bin_deg, c.max_incidence_deg);
            response.level_db.assign(static_cast<std::size_t>(bins), 0.0);
            response.counts.assign(static_cast<std::size_t>(bins), 0);
            break;
        }
    }
    return response;
}

// The second pass: every node's mean level, corrected to the reference angle and not, its count,
// the used soundings' median incidence and the spread of the corrected means.
void GridMeans(const LevelledSoundings& levelled,
               std::size_t cells,
               const MosaicConfig& c,
               MosaicResult& r) {
    const double reference_db = r.response.At(c.reference_angle_deg);
    std::vector<double> corrected_sum_db(cells, 0.0);
    std::vector<std::uint32_t> count(cells, 0);
    std::vector<float> used_incidence;
    used_incidence.reserve(levelled.node.size());
    for (std::size_t j = 0; j < levelled.node.size(); ++j) {
        const std::uint32_t cell = levelled.node[j];
        if (cell == kNoNode) continue;
        corrected_sum_db[cell] +=
            levelled.level_db[j] - r.response.At(levelled.incidence_deg[j]) + reference_db;
        ++count[cell];
        used_incidence.push_back(levelled.incidence_deg[j]);
        ++r.used;
    }
    r.corrected_db.assign(cells, kNaN);
    r.uncorrected_db.assign(cells, kNaN);
    r.count.assign(cells, 0.0f);
    std::vector<float> filled;
    for (std::size_t cell = 0; cell < cells; ++cell) {
        if (count[cell] == 0) continue;
        r.corrected_db[cell] = static_cast<float>(corrected_sum_db[cell] / count[cell]);
        r.uncorrected_db[cell] =
            static_cast<float>(levelled.uncorrected_sum_db[cell] / count[cell]);
        r.count[cell] = static_cast<float>(count[cell]);
        filled.push_back(r.corrected_db[cell]);
    }
    r.nodes_filled = static_cast<std::int64_t>(filled.size());
    r.median_incidence_deg = Percentile(used_incidence, 0.5);
    r.corrected_p05_db = Percentile(filled, 0.05);
    r.corrected_p95_db = Percentile(filled, 0.95);
}

std::string MosaicMessage(const MosaicResult& r, const MosaicConfig& c) {
    char buf[320];
    std::snprintf(buf,
                  sizeof buf,
                  "%lld of %lld soundings on %lld nodes (no intensity %lld, saturated %lld, "
                  "outside %lld, incidence > %.0f deg %lld); %s angular response; corrected "
                  "5-95 %% %.1f..%.1f dB",
                  static_cast<long long>(r.used),
                  static_cast<long long>(r.soundings_in),
                  static_cast<long long>(r.nodes_filled),
                  static_cast<long long>(r.no_intensity),
                  static_cast<long long>(r.saturated),
                  static_cast<long long>(r.outside_grid),
                  c.max_incidence_deg,
                  static_cast<long long>(r.beyond_incidence),
                  ToString(c.angular),
                  r.corrected_p05_db,
                  r.corrected_p95_db);
    return r.ok ? std::string(buf) : "no usable intensity: " + std::string(buf);
}

}  // namespace

struct MosaicByBlocks::State {
    const MosaicGrid& grid;
    MosaicConfig config;
    std::size_t cells = 0;
    LevelledSoundings levelled;
    std::vector<Eigen::Vector3d> normals;
    std::vector<char> have_normal;
    MosaicResult result;

    State(const MosaicGrid& g, const MosaicConfig& c) : grid(g), config(c) {
        cells = static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny);
        levelled.uncorrected_sum_db.assign(cells, 0.0);
        normals.assign(cells, Eigen::Vector3d::Zero());
        have_normal.assign(cells, 0);
    }
};

MosaicByBlocks::MosaicByBlocks(const MosaicGrid& g, const MosaicConfig& c) {
    PITMAP_CHECK(g.elevation_m != nullptr && g.nx > 0 && g.ny > 0 && g.resolution_m > 0 &&
                     g.elevation_m->size() ==
                         static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny),
                 "RunMosaic: bad grid");
    state_ = std::make_unique<State>(g, c);
}

MosaicByBlocks::~MosaicByBlocks() = default;

void MosaicByBlocks::Reserve(std::size_t n) {
    state_->levelled.node.reserve(n);
    state_->levelled.level_db.reserve(n);
    state_->levelled.incidence_deg.reserve(n);
}

void MosaicByBlocks::Add(const MosaicSoundings& block) {
    const std::size_t n = block.size();
    PITMAP_CHECK(block.y.size() == n && block.intensity.size() == n && block.range_m.size() == n &&
                     block.beam_dir.size() == n,
                 "RunMosaic: soundings arrays differ in size");
    State& st = *state_;
    st.result.soundings_in += static_cast<std::int64_t>(n);
    LevelSoundings(block, st.grid, st.config, st.normals, st.have_normal, st.levelled, st.result);
}

// With the angular response, the nodes' corrected means.
MosaicResult MosaicByBlocks::Finish() {
    State& st = *state_;
    std::vector<Eigen::Vector3d>().swap(st.normals);
    std::vector<char>().swap(st.have_normal);
    MosaicResult r = std::move(st.result);
    const MosaicConfig& c = st.config;
    r.response = ChosenAngularResponse(st.levelled, st.cells, c);
    GridMeans(st.levelled, st.cells, c, r);
    st.levelled = LevelledSoundings{};
    r.ok = r.used > 0;
    r.message = MosaicMessage(r, c);
    return r;
}

// Two passes over the soundings: their range-corrected levels and incidences on the DEM, then,
// with the angular response, the nodes' corrected means.
MosaicResult RunMosaic(MosaicSoundings s, const MosaicGrid& g, const MosaicConfig& c) {
    MosaicByBlocks blocks(g, c);
    blocks.Add(s);
    s = MosaicSoundings{};  // what follows needs only the nodes, levels and incidences
    return blocks.Finish();
}

}  // namespace pitmap::proc::hydro
