// SPDX-License-Identifier: MIT
// Geoid undulations through PROJ (Debian's libproj with proj-data's grids): N = geoid height
// above the WGS 84 ellipsoid at a latitude and longitude, from a vertical grid such as
// proj-data's egm96_15.gtx (EGM96, 15' grid, bilinear as PROJ's vgridshift interpolates).
// The grid is named as PROJ finds it (a file name in PROJ's data directories, or a path);
// network access is switched off, so a grid that is not on this machine is an error that names
// it, never a silent zero.
// Failure model: Expected errors naming the grid; a point outside the grid is an error.
// Thread safety: one GeoidGrid per thread.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "common/geodesy.hpp"
#include "common/result.hpp"

namespace pitmap::proc::io {

class GeoidGrid {
public:
    // Opens the grid; fails when PROJ cannot find or read it.
    static Expected<GeoidGrid> Open(const std::string& grid);
    ~GeoidGrid();
    GeoidGrid(GeoidGrid&&) noexcept;
    GeoidGrid& operator=(GeoidGrid&&) noexcept;

    // N in metres at each point (heights ignored); fails naming the first point the grid
    // does not cover.
    Expected<std::vector<double>> Undulations(const std::vector<Geodetic>& points) const;
    const std::string& name() const { return name_; }

private:
    GeoidGrid() = default;
    struct Impl;
    std::unique_ptr<Impl> impl_;
    std::string name_;
};

}  // namespace pitmap::proc::io
