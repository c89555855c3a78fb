// SPDX-License-Identifier: MIT
// The georeferenced 3D products (issue 39, docs/georeferencing.md): the soundings and the mesh
// in the products' projected CRS (UTM + the vertical datum), beside the local ENU files the
// viewer reads.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <filesystem>

#include "common/geodesy.hpp"
#include "processor/io/geoid.hpp"
#include "processor/io/products.hpp"
#include "processor/io/projected_points.hpp"
#include "processor/mesh/export.hpp"
#include "processor/pipeline/grid_cube_tiles.hpp"
#include "processor/pipeline/internal.hpp"

namespace pitmap::proc::pipeline::detail {

namespace {

// "WGS 84 / UTM zone 29N + EGM96 height"
std::string CrsName(int zone, bool northern, const hydro::DatumModel& datum) {
    return "WGS 84 / UTM zone " + std::to_string(zone) + (northern ? "N" : "S") + " + " +
           datum.crs_name;
}

}  // namespace

Status WriteProjectedPoints(const std::string& dir,
                            const georef::GeorefResult& geo,
                            const georef::UtmProjection& utm,
                            const georef::GeorefResult* rejected,
                            const hydro::DatumModel& datum,
                            const ProductMetadata& meta,
                            const std::string& run_id,
                            std::size_t block_soundings) {
    const AcceptedPointsReader held = [&geo](std::size_t first,
                                             std::size_t,
                                             const georef::GeorefPoints*& points,
                                             std::size_t& offset) {
        points = &geo.points;
        offset = first;
        return Status{Ok{}};
    };
    return WriteProjectedPointsOf(dir,
                                  geo.pings,
                                  geo.points.size(),
                                  held,
                                  utm,
                                  rejected,
                                  datum,
                                  meta,
                                  run_id,
                                  block_soundings);
}

Status WriteProjectedPointsOf(const std::string& dir,
                              const std::vector<georef::GeorefPing>& pings,
                              std::size_t num_accepted,
                              const AcceptedPointsReader& read_accepted,
                              const georef::UtmProjection& utm,
                              const georef::GeorefResult* rejected,
                              const hydro::DatumModel& datum,
                              const ProductMetadata& meta,
                              const std::string& run_id,
                              std::size_t block_soundings) {
    io::ProjectedPoints crs;
    crs.crs_name = CrsName(utm.zone, utm.northern, datum);
    crs.horizontal_epsg = utm.epsg;
    crs.vertical_epsg = datum.vertical_epsg;
    const auto D = [&datum](std::uint32_t ping) {
        return ping < datum.datum_height_m.size() ? datum.datum_height_m[ping] : 0.0;
    };
    georef::UtmProjection rejected_utm;
    const bool with_rejected = rejected != nullptr && rejected->points.size() > 0 &&
                               rejected->points.status.size() == rejected->points.size();
    if (with_rejected) {
        auto r = georef::UtmProjectionOf(*rejected);
        if (!r)
            return Error{dir +
                         "/points_utm.ply: UTM of the rejected soundings: " + r.error().message};
        rejected_utm = std::move(*r);
    }
    const std::size_t n = num_accepted + (with_rejected ? rejected->points.size() : 0);
    Status read_status = Ok{};
    // Point j: accepted sounding j, then rejected sounding j - num_accepted; placed where the
    // block is made (georef::UtmProjection), not held for the survey. The accepted soundings
    // of a block are read (read_accepted) before it is made.
    const auto fill = [&](std::size_t first, std::span<io::ProjectedPoint> out) {
        const georef::GeorefPoints* accepted_points = nullptr;
        std::size_t offset = 0;
        if (first < num_accepted && read_status) {
            const std::size_t count = std::min(out.size(), num_accepted - first);
            read_status = read_accepted(first, count, accepted_points, offset);
        }
        if (!read_status) return;
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, out.size(), 4096),
            [&](const tbb::blocked_range<std::size_t>& r) {
                for (std::size_t k = r.begin(); k != r.end(); ++k) {
                    const std::size_t j = first + k;
                    const bool accepted = j < num_accepted;
                    const georef::GeorefPoints& g = accepted ? *accepted_points : rejected->points;
                    const std::vector<georef::GeorefPing>& gp = accepted ? pings : rejected->pings;
                    const std::size_t i = accepted ? offset + k : j - num_accepted;
                    const std::uint32_t ping = g.ping[i];
                    const Eigen::Vector3d enh =
                        accepted ? utm.At(g, gp, i) : rejected_utm.At(g, gp, i);
                    out[k] = {enh - Eigen::Vector3d(0, 0, D(ping)),
                              static_cast<double>(gp[ping].utime_gps) * 1e-6,
                              accepted ? std::uint8_t{0} : g.status[i]};
                }
            });
    };
    const std::string path = dir + "/points_utm.ply";
    auto w = io::WriteProjectedPointsPly(path, crs, n, block_soundings, fill, &meta, run_id);
    if (!read_status) {
        std::error_code ec;
        std::filesystem::remove(path, ec);
        return Error{path + ": " + read_status.error().message};
    }
    if (!w) return w;
    return io::WritePrj(dir + "/points_utm.prj",
                        io::LasWkt(utm.zone, utm.northern, datum.VerticalWkt()));
}

Expected<mesh::ProjectedMesh> ProjectMesh(const mesh::ColouredMesh& m,
                                          const Geodetic& origin,
                                          const hydro::DatumModel& datum,
                                          const PipelineConfig& config) {
    auto zone = UtmFromGeodetic(origin);
    if (!zone || zone->zone < 1) return Error{"mesh: the world origin has no UTM zone"};
    const int z = zone->zone;
    const bool north = zone->northern;
    const LocalTangentFrame world(origin);
    const std::size_t n = m.vertices.size();
    std::vector<Geodetic> geo(n);
    mesh::ProjectedMesh p;
    p.positions.resize(n);
    std::vector<char> failed(n, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              geo[i] = world.FromEnu(m.vertices[i].cast<double>());
                              const auto u = UtmFromGeodetic(geo[i], z);
                              if (!u) {
                                  failed[i] = 1;
                                  continue;
                              }
                              p.positions[i] = {u->easting_m, u->northing_m, u->height_m};
                          }
                      });
    for (std::size_t i = 0; i < n; ++i) {
        if (failed[i]) return Error{"mesh: vertex " + std::to_string(i) + " has no UTM position"};
    }
    // The vertical datum: the geoid where each vertex lies; a water level (or the ellipsoid)
    // as its mean over the survey (a mesh vertex has no time: a file's levels that change
    // during the survey move the points' and DEM's heights by their change, not the mesh's).
    if (datum.datum == hydro::VerticalDatum::kGeoid) {
        const hydro::VerticalDatumConfig& vc = config.grid.vertical;
        const hydro::GeoidCrs* g = hydro::FindGeoidCrs(datum.vertical_epsg);
        const std::string grid =
            vc.geoid_grid.empty() && g != nullptr ? g->default_grid : vc.geoid_grid;
        auto geoid = io::GeoidGrid::Open(grid);
        if (!geoid) return Error{"mesh: vertical datum: " + geoid.error().message};
        auto und = geoid->Undulations(geo);
        if (!und) return Error{"mesh: vertical datum: " + und.error().message};
        for (std::size_t i = 0; i < n; ++i) p.positions[i].z() -= (*und)[i];
    } else {
        for (auto& x : p.positions) x.z() -= datum.mean_datum_height_m;
    }
    mesh::SetOffset(p);
    p.crs_name = CrsName(z, north, datum);
    p.crs_wkt = io::LasWkt(z, north, datum.VerticalWkt());
    p.horizontal_epsg = UtmEpsgCode(z, north);
    p.vertical_epsg = datum.vertical_epsg;
    return p;
}

}  // namespace pitmap::proc::pipeline::detail
