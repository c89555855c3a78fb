// SPDX-License-Identifier: MIT
// The grid stage's CUBE by bands of node rows (decision 035): CUBE's input (48 bytes a sounding)
// waits in a scratch file in the products folder, and each band of the survey's node rows is
// gridded alone (hydro::RunCubeTile) from the soundings of its cells and their halo, read from
// that file, node for node the whole survey's grid; the surface filter's verdicts are made from
// the file a block at a time. With the view's blocks (ForEachViewBlock, decision 031), no part of
// the stage holds the survey's CUBE input or its view whole.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/hydro/cube.hpp"
#include "processor/io/record_spill.hpp"
#include "processor/pipeline/grid_stage.hpp"
#include "processor/pipeline/internal.hpp"
#include "processor/pipeline/tiles.hpp"

namespace pitmap::proc::pipeline::detail {

// CUBE's own test after it has chosen (grid_stage.cpp): the surface filter's verdict of each
// sounding (0 = kept) against the grid `g`.
std::vector<std::uint8_t> SurfaceFilter(const std::vector<hydro::CubeSounding>& snd,
                                        const hydro::CubeGrid& g,
                                        const GridStageConfig& gc);

// CUBE's input in the survey's order, on disk: P/.partial-cube_input.
class CubeInputFile {
public:
    static Expected<CubeInputFile> Create(const std::string& out_dir);
    // Appends soundings (in the survey's order) while writing; Close ends it.
    Status Append(const std::vector<hydro::CubeSounding>& soundings);
    Status Close() { return file_.Close(); }
    // Calls fn(block, first) on the soundings a block of `block` at a time, in order.
    Status ForEachBlock(std::size_t block,
                        const std::function<Status(const std::vector<hydro::CubeSounding>&,
                                                   std::size_t)>& fn) const;
    // The file with only the soundings whose keep[j] is non-zero, in their order (a second
    // file; this one is then removed). keep: one per sounding.
    Expected<CubeInputFile> KeepOnly(const std::vector<char>& keep, std::size_t block) const;
    std::size_t size() const { return file_.size(); }
    const std::string& path() const { return file_.path(); }

private:
    explicit CubeInputFile(io::RecordFile file) : file_(std::move(file)) {}
    io::RecordFile file_;
};

// CUBE over the soundings of `input` by bands of whole node rows: the layout (LayOutCube's, from
// one pass over the file), the soundings counted by predicted-surface cell row, bands each
// reading at most 4 `block` soundings and holding at most `block` nodes, the soundings handed
// to the bands' own scratch files in one pass (64 bands a pass), and each band gridded alone
// (hydro::RunCubeTile with CubeTileReach of halo) and pasted into the survey's grid. The result
// is RunCube's: every node bit for bit, the counters and the message (with tiles.enabled, the
// tiled message of before). ok = false with the message where RunCube would fail; an error
// when a scratch file fails. `bands`: how many bands CUBE took.
Expected<hydro::CubeResult> CubeByBands(const CubeInputFile& input,
                                        const GridStageConfig& gc,
                                        const TilesConfig& tiles,
                                        std::size_t block,
                                        std::size_t* bands = nullptr);

// SurfaceFilter's verdicts of the soundings of `input` on grid `g`, a block at a time: one a
// sounding, in order.
Expected<std::vector<std::uint8_t>> SurfaceVerdicts(const CubeInputFile& input,
                                                    const hydro::CubeGrid& g,
                                                    const GridStageConfig& gc,
                                                    std::size_t block);

}  // namespace pitmap::proc::pipeline::detail
