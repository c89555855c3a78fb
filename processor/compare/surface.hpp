// SPDX-License-Identifier: MIT
// A gridded surface as `pitmap compare` uses it: the heights of one survey's CUBE surface
// (dem.tif) and their 1-sigma, on a north-up grid in a projected CRS (metres).
// Node (i, j) is at (x0 + i res, y0 + j res), row j = 0 the southernmost; NaN = no data.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <vector>

namespace pitmap::proc::compare {

struct SurfaceGrid {
    double x0 = 0, y0 = 0;  // node (0, 0), m
    double resolution_m = 0;
    int nx = 0, ny = 0;
    std::vector<float> z_m;      // heights, up; NaN = empty
    std::vector<float> sigma_m;  // 1-sigma of each height (dem.tif's 95 % uncertainty / 1.96)
    // Soundings behind each node (dem.tif's density band: those in CUBE's chosen hypothesis);
    // empty when not known (a design surface, a grid from elsewhere).
    std::vector<float> density;

    std::size_t index(int i, int j) const {
        return static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) +
               static_cast<std::size_t>(i);
    }
    bool filled(int i, int j) const { return std::isfinite(z_m[index(i, j)]); }
    // Bilinear height at (x, y); NaN when a corner of its cell is empty or it is outside.
    double HeightAt(double x, double y) const;
    // Bilinear 1-sigma at (x, y); NaN likewise.
    double SigmaAt(double x, double y) const;
    // The fewest soundings behind the nodes HeightAt(x, y) interpolates (the four corners of
    // its cell); +inf when the density is not known, NaN outside the grid.
    double MinDensityAt(double x, double y) const;
    // Filled nodes.
    std::size_t CountFilled() const;
};

// The surface smoothed by a square mean of (2 radius + 1)^2 nodes over the filled ones (a node
// stays empty if it was); radius 0 returns a copy.
SurfaceGrid Smoothed(const SurfaceGrid& s, int radius_nodes);

// The surface filtered by the separable tent of half-width k nodes (weights (k - |i|) / k along
// each axis, over the filled nodes, renormalised; a node stays empty if it was); k <= 1 returns
// a copy. Bilinear interpolation of a grid of spacing k res is this tent over its nodes: so a
// surface of spacing res filtered by it resolves what the coarser one does (pitmap compare, two
// grids of different resolution).
SurfaceGrid TentFiltered(const SurfaceGrid& s, int k);

// Central-difference gradient (dz/dx, dz/dy) at node (i, j) over +-step nodes; nullopt-like
// NaN vector when a neighbour is empty.
Eigen::Vector2d GradientAt(const SurfaceGrid& s, int i, int j, int step);

}  // namespace pitmap::proc::compare
