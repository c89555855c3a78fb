// SPDX-License-Identifier: MIT
// The `grid` stage: total propagated uncertainty of every sounding (processor/hydro/tpu.hpp)
// and a CUBE surface (processor/hydro/cube.hpp) in the survey's UTM zone, written as
//   P/dem.tif          Cloud Optimized GeoTIFF, bands elevation, uncertainty (95 %), density,
//                      hypotheses; WGS 84 / UTM zone + WGS 84 ellipsoidal height
//   P/dem.bag          BAG: elevation and uncertainty, same CRS
//   P/soundings_tpu.ply  (grid.write_sounding_tpu) per sounding: float x, y, z (world ENU, as
//                      points.ply), double gps_time_s, float angle_deg (beam angle), float
//                      thu_95_m, tvu_95_m; comment "pitmap_origin LAT LON H"
//   P/mosaic.tif       (mosaic.enabled, when the pings carry 83P intensities) Cloud Optimized
//                      GeoTIFF on the DEM's grid, WGS 84 / UTM zone only: bands backscatter (dB,
//                      relative, corrected for range and incidence: hydro/mosaic.hpp),
//                      uncorrected (mean 20 log10 intensity, dB) and count
//   P/terrain.tif      (terrain.enabled) the mine-planning layers on the DEM's grid
//                      (hydro/terrain.hpp): bands slope (deg), roughness (m) and step (m)
//   P/crawler.tif      (terrain.enabled) a Byte class map: where a crawler of the configured
//                      limits can stand, and what it can reach from terrain.launch_*
// and summary.json stages.grid (stages.grid.mosaic, stages.grid.terrain). It runs on the soundings
// of the last stage (after SLAM, or after georef / calibrate when SLAM is off). The error model is
// vehicle.yaml's `uncertainty:` section (summary.json vehicle_yaml), else SensorErrorModel's
// defaults; the INS sigmas are the logs' INSSTDEV records nearest each ping (within
// ins_sigma_max_age_s), else the model's.
#pragma once

#include <string>
#include <vector>

#include "processor/hydro/cube.hpp"
#include "processor/hydro/datum.hpp"
#include "processor/hydro/mosaic.hpp"
#include "processor/hydro/s44.hpp"
#include "processor/hydro/sound_speed.hpp"
#include "processor/hydro/terrain.hpp"

namespace pitmap::proc::pipeline {

struct GridStageConfig {
    bool in_run = true;                 // `pitmap run` makes the grid
    hydro::CubeConfig cube;             // CUBE parameters (resolution 0 = from the depth)
    double tpu_sound_speed_mps = 1500;  // nominal sound speed for the TPU's sound-speed terms
    double ins_sigma_max_age_s = 5.0;   // INSSTDEV records further from a ping are not used
    // The TPU's pose sigma: SLAM's posterior (slam.posterior) where the soundings stand on the
    // SLAM trajectory, else the INS's own; false = the INS's own everywhere (which after SLAM
    // states an outage's metres where SLAM left centimetres). docs/uncertainty.md, decision 016.
    bool tpu_slam_posterior = true;
    // The TPU's sound speed terms from the data (processor/hydro/sound_speed.hpp): the casts'
    // age, distance and disagreement with the sonar's surface speed, and the column speed error
    // the swath overlap measures; false = the error model's sound speed sigmas alone.
    bool tpu_sound_speed_from_data = true;
    hydro::SoundSpeedSigmaConfig sound_speed;
    bool write_geotiff = true;        // P/dem.tif
    bool write_bag = true;            // P/dem.bag
    bool write_sounding_tpu = false;  // P/soundings_tpu.ply (28 bytes a sounding)
    bool write_point_tpu = true;      // points.ply / points.las again with THU, TVU (and datum)
    // The surface filter (issue 35): soundings off the CUBE surface's chosen hypothesis on
    // floors are rejected (grid_stage.cpp SurfaceFilter).
    bool surface_filter = true;
    double surface_filter_gate = 4.0;            // combined 1-sigma multiple (CUBE's own gate)
    double surface_filter_min_m = 0.15;          // ... and at least this far, m
    double surface_filter_max_slope_deg = 30.0;  // floors only: steeper is the 3D cleaning's
    hydro::VerticalDatumConfig vertical;         // the `vertical:` section: the products' datum
    bool s44 = true;                             // S-44 quality control (`s44:` section)
    hydro::S44Config s44_config;
    bool mosaic = true;  // backscatter mosaic (`mosaic:` section), when the
                         // pings carry intensities
    hydro::MosaicConfig mosaic_config;
    bool terrain = true;  // mine-planning layers (`terrain:` section): terrain.tif, crawler.tif
    hydro::TerrainConfig terrain_config;

    std::vector<std::string> Validate() const;
};

// The `grid:` section of the config is read and printed by the one config key table
// (config.cpp, VisitGrid).

}  // namespace pitmap::proc::pipeline
