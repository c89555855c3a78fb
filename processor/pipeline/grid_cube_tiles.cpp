// SPDX-License-Identifier: MIT
// The grid stage's CUBE by bands of node rows (grid_cube_tiles.hpp, decision 035) and the view
// read a block at a time (decision 031).
#include "processor/pipeline/grid_cube_tiles.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>
#include <type_traits>
#include <utility>

#include "common/formats/replace_file.hpp"

namespace pitmap::proc::pipeline::detail {

namespace {

static_assert(std::is_trivially_copyable_v<hydro::CubeSounding>);

constexpr std::size_t kBandsAPass = 64;    // band files open at once
constexpr std::size_t kBandBuffer = 4096;  // soundings buffered a band before a write
constexpr std::size_t kBandBlocks = 4;     // a band reads at most this many blocks' soundings

// A band's soundings on their way to its scratch file.
struct BandSink {
    io::RecordFile file;
    std::vector<hydro::CubeSounding> buffer;

    Status Flush() {
        auto st = file.Append(buffer.data(), buffer.size());
        buffer.clear();
        return st;
    }
};

// The soundings of bands [first, last) handed to their own scratch files in one pass over
// `input`, each in the input's order (a sounding goes to every band whose cell rows hold it).
Expected<std::vector<BandSink>> DistributeToBands(const CubeInputFile& input,
                                                  const std::vector<hydro::CubeBand>& bands,
                                                  std::size_t first,
                                                  std::size_t last,
                                                  double res,
                                                  const hydro::CubeConfig& cube,
                                                  std::size_t block) {
    std::vector<BandSink> sinks;
    for (std::size_t b = first; b < last; ++b) {
        auto f = io::RecordFile::Create(input.path() + "_band_" + std::to_string(b),
                                        sizeof(hydro::CubeSounding));
        if (!f) return f.error();
        sinks.push_back({std::move(*f), {}});
        sinks.back().buffer.reserve(kBandBuffer);
    }
    const auto begin = bands.begin() + static_cast<std::ptrdiff_t>(first);
    const auto end = bands.begin() + static_cast<std::ptrdiff_t>(last);
    auto st =
        input.ForEachBlock(block, [&](const std::vector<hydro::CubeSounding>& snd, std::size_t) {
            for (const hydro::CubeSounding& q : snd) {
                if (!hydro::CubeTakes(q)) continue;
                const std::int64_t row = hydro::CubeCellIndex(q.y, res, cube);
                // The bands' cell rows rise with the bands: the first whose last row reaches `row`.
                auto it = std::partition_point(
                    begin, end, [&](const hydro::CubeBand& band) { return band.cells.last < row; });
                for (; it != end && it->cells.first <= row; ++it) {
                    BandSink& sink = sinks[static_cast<std::size_t>(it - begin)];
                    sink.buffer.push_back(q);
                    if (sink.buffer.size() >= kBandBuffer) {
                        if (auto w = sink.Flush(); !w) return w;
                    }
                }
            }
            return Status{Ok{}};
        });
    if (!st) return st.error();
    for (BandSink& sink : sinks) {
        if (auto w = sink.Flush(); !w) return w.error();
        if (auto w = sink.file.Close(); !w) return w.error();
        std::vector<hydro::CubeSounding>().swap(sink.buffer);
    }
    return sinks;
}

// Tile `t`'s nodes pasted into the survey's grid `g` (its layers), its counters added.
void PasteTile(const hydro::CubeResult& t, hydro::CubeResult& out) {
    hydro::CubeGrid& g = out.grid;
    for (int j = 0; j < t.grid.ny; ++j) {
        const std::size_t to =
            static_cast<std::size_t>(t.grid.j0 + j - g.j0) * g.nx + (t.grid.i0 - g.i0);
        const std::size_t from = static_cast<std::size_t>(j) * t.grid.nx;
        const auto n = static_cast<std::ptrdiff_t>(t.grid.nx);
        const auto paste = [&](const std::vector<float>& a, std::vector<float>& b) {
            std::copy(a.begin() + static_cast<std::ptrdiff_t>(from),
                      a.begin() + static_cast<std::ptrdiff_t>(from) + n,
                      b.begin() + static_cast<std::ptrdiff_t>(to));
        };
        paste(t.grid.elevation_m, g.elevation_m);
        paste(t.grid.uncertainty_m, g.uncertainty_m);
        paste(t.grid.density, g.density);
        paste(t.grid.hypotheses, g.hypotheses);
    }
    out.node_updates += t.node_updates;
    out.nodes_filled += t.nodes_filled;
    out.nodes_multiple += t.nodes_multiple;
    out.hypotheses_total += t.hypotheses_total;
}

// LayOutCube over the file's soundings (one pass; 4 bytes a sounding held).
Expected<hydro::CubeResult> LayOutFromFile(const CubeInputFile& input,
                                           const hydro::CubeConfig& cube,
                                           std::size_t block) {
    hydro::CubeLayout layout;
    layout.Reserve(input.size());
    auto st =
        input.ForEachBlock(block, [&](const std::vector<hydro::CubeSounding>& snd, std::size_t) {
            for (const hydro::CubeSounding& q : snd) layout.Add(q);
            return Status{Ok{}};
        });
    if (!st) return st.error();
    return layout.Finish(cube);
}

// The soundings CUBE takes in each predicted-surface cell row of the survey's grid, from
// `first_cell`.
Expected<std::vector<std::int64_t>> SoundingsByCellRow(const CubeInputFile& input,
                                                       const hydro::CubeGrid& g,
                                                       const hydro::CubeConfig& cube,
                                                       std::size_t block,
                                                       std::int64_t& first_cell) {
    const double res = g.resolution_m;
    first_cell = hydro::CubeCellIndex(g.y0, res, cube);
    const std::int64_t last_cell =
        hydro::CubeCellIndex(static_cast<double>(g.j0 + g.ny) * res, res, cube);
    std::vector<std::int64_t> counts(static_cast<std::size_t>(last_cell - first_cell + 1), 0);
    auto st =
        input.ForEachBlock(block, [&](const std::vector<hydro::CubeSounding>& snd, std::size_t) {
            for (const hydro::CubeSounding& q : snd) {
                if (!hydro::CubeTakes(q)) continue;
                const std::int64_t b =
                    std::clamp(hydro::CubeCellIndex(q.y, res, cube), first_cell, last_cell);
                ++counts[static_cast<std::size_t>(b - first_cell)];
            }
            return Status{Ok{}};
        });
    if (!st) return st.error();
    return counts;
}

// The message of before for tiles.enabled (the grid tiles and their overlap).
std::string TiledMessage(const hydro::CubeResult& out, const TilesConfig& tiles) {
    const hydro::CubeGrid& g = out.grid;
    const double res = g.resolution_m;
    const std::size_t n =
        GridTiles({g.i0, g.j0, g.i0 + g.nx, g.j0 + g.ny}, NodesPerTile(tiles, res)).size();
    return std::to_string(g.nx) + " x " + std::to_string(g.ny) + " nodes at " + Fixed(res, 3) +
           " m in " + std::to_string(n) + " tiles of " + std::to_string(NodesPerTile(tiles, res)) +
           " nodes (overlap " + Fixed(tiles.overlap_m, 1) +
           " m): " + std::to_string(out.nodes_filled) + " filled, " +
           std::to_string(out.nodes_multiple) + " with several hypotheses; " +
           std::to_string(out.soundings_used) + " soundings, " + std::to_string(out.node_updates) +
           " node updates";
}

// Bands [first, last) of `bands` gridded and pasted into `out`.
Status GridBands(const CubeInputFile& input,
                 const std::vector<hydro::CubeBand>& bands,
                 std::size_t first,
                 std::size_t last,
                 const hydro::CubeConfig& cube,
                 double overlap_m,
                 std::size_t block,
                 hydro::CubeResult& out) {
    const hydro::CubeGrid& g = out.grid;
    const hydro::CubeNodeRange survey{g.i0, g.j0, g.i0 + g.nx, g.j0 + g.ny};
    auto sinks = DistributeToBands(input, bands, first, last, g.resolution_m, cube, block);
    if (!sinks) return sinks.error();
    std::vector<hydro::CubeSounding> snd;
    for (std::size_t b = first; b < last; ++b) {
        io::RecordFile& file = (*sinks)[b - first].file;
        snd.resize(file.size());
        auto st = file.ForEachBlock(std::max<std::size_t>(file.size(), 1),
                                    [&](std::size_t, std::size_t count, const std::byte* bytes) {
                                        std::memcpy(
                                            snd.data(), bytes, count * sizeof(hydro::CubeSounding));
                                        return Status{Ok{}};
                                    });
        if (!st) return st;
        const hydro::CubeResult t = hydro::RunCubeTile(snd, cube, bands[b].core, survey, overlap_m);
        if (!t.ok) return Error{"grid: CUBE band " + std::to_string(b) + ": " + t.message};
        PasteTile(t, out);
    }
    return Ok{};
}

}  // namespace

Expected<CubeInputFile> CubeInputFile::Create(const std::string& out_dir) {
    const std::string path =
        (std::filesystem::path(out_dir) / (std::string(formats::kPartialPrefix) + "cube_input"))
            .string();
    auto f = io::RecordFile::Create(path, sizeof(hydro::CubeSounding));
    if (!f) return f.error();
    return CubeInputFile(std::move(*f));
}

Status CubeInputFile::Append(const std::vector<hydro::CubeSounding>& soundings) {
    return file_.Append(soundings.data(), soundings.size());
}

Status CubeInputFile::ForEachBlock(
    std::size_t block,
    const std::function<Status(const std::vector<hydro::CubeSounding>&, std::size_t)>& fn) const {
    std::vector<hydro::CubeSounding> snd;
    return file_.ForEachBlock(block, [&](std::size_t first, std::size_t count, const std::byte* b) {
        snd.resize(count);
        std::memcpy(snd.data(), b, count * sizeof(hydro::CubeSounding));
        return fn(snd, first);
    });
}

Expected<CubeInputFile> CubeInputFile::KeepOnly(const std::vector<char>& keep,
                                                std::size_t block) const {
    if (keep.size() != size())
        return Error{path() + ": " + std::to_string(keep.size()) + " verdicts for " +
                     std::to_string(size()) + " soundings"};
    const std::string kept_suffix = "_kept";
    const bool is_kept =
        path().size() > kept_suffix.size() &&
        path().compare(path().size() - kept_suffix.size(), kept_suffix.size(), kept_suffix) == 0;
    const std::string to =
        is_kept ? path().substr(0, path().size() - kept_suffix.size()) : path() + kept_suffix;
    auto f = io::RecordFile::Create(to, sizeof(hydro::CubeSounding));
    if (!f) return f.error();
    CubeInputFile out(std::move(*f));
    std::vector<hydro::CubeSounding> part;
    auto st =
        ForEachBlock(block, [&](const std::vector<hydro::CubeSounding>& snd, std::size_t first) {
            part.clear();
            for (std::size_t i = 0; i < snd.size(); ++i) {
                if (keep[first + i]) part.push_back(snd[i]);
            }
            return out.Append(part);
        });
    if (!st) return st.error();
    if (auto c = out.Close(); !c) return c.error();
    return out;
}

Expected<hydro::CubeResult> CubeByBands(const CubeInputFile& input,
                                        const GridStageConfig& gc,
                                        const TilesConfig& tiles,
                                        std::size_t block,
                                        std::size_t* bands_taken) {
    auto laid = LayOutFromFile(input, gc.cube, block);
    if (!laid) return laid.error();
    hydro::CubeResult out = std::move(*laid);
    if (!out.ok) return out;
    const double res = out.grid.resolution_m;
    if (tiles.enabled) {
        if (const auto problems = ValidateGridTiles(tiles, res, gc.cube); !problems.empty()) {
            out.ok = false;
            out.message = "grid: " + problems.front();
            for (std::size_t k = 1; k < problems.size(); ++k) out.message += "; " + problems[k];
            return out;
        }
    }
    hydro::CubeConfig cube = gc.cube;
    cube.resolution_m = res;
    const double overlap_m = hydro::CubeTileReach(res, cube);
    std::int64_t first_cell = 0;
    auto counts = SoundingsByCellRow(input, out.grid, cube, block, first_cell);
    if (!counts) return counts.error();
    const auto most = static_cast<std::int64_t>(std::max<std::size_t>(block, 1));
    const std::vector<hydro::CubeBand> bands =
        hydro::PlanCubeBands(out.grid,
                             first_cell,
                             *counts,
                             cube,
                             overlap_m,
                             static_cast<std::int64_t>(kBandBlocks) * most,
                             most);
    hydro::CubeGrid& g = out.grid;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    g.elevation_m.assign(g.size(), nan);
    g.uncertainty_m.assign(g.size(), nan);
    g.density.assign(g.size(), 0.0f);
    g.hypotheses.assign(g.size(), 0.0f);
    for (std::size_t first = 0; first < bands.size(); first += kBandsAPass) {
        const std::size_t last = std::min(bands.size(), first + kBandsAPass);
        if (auto st = GridBands(input, bands, first, last, cube, overlap_m, block, out); !st)
            return st.error();
    }
    if (bands_taken != nullptr) *bands_taken = bands.size();
    out.message = tiles.enabled ? TiledMessage(out, tiles) : hydro::DescribeCube(out);
    return out;
}

Expected<std::vector<std::uint8_t>> SurfaceVerdicts(const CubeInputFile& input,
                                                    const hydro::CubeGrid& g,
                                                    const GridStageConfig& gc,
                                                    std::size_t block) {
    std::vector<std::uint8_t> verdict;
    verdict.reserve(input.size());
    auto st =
        input.ForEachBlock(block, [&](const std::vector<hydro::CubeSounding>& snd, std::size_t) {
            const std::vector<std::uint8_t> v = SurfaceFilter(snd, g, gc);
            verdict.insert(verdict.end(), v.begin(), v.end());
            return Status{Ok{}};
        });
    if (!st) return st.error();
    return verdict;
}

}  // namespace pitmap::proc::pipeline::detail
