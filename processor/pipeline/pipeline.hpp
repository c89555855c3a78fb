// SPDX-License-Identifier: MIT
// Composition of the stages on a products folder P (the `pitmap` subcommands):
//   georef:    inputs -> ingest -> georef -> P/points.ply, points.las, trajectory.csv,
//              boresight.json (the mount used), ingest.cache, summary.json
//   calibrate: P/ingest.cache + P/summary.json -> boresight calibration -> re-georeference ->
//              P/boresight.json, points.ply, points.las, summary.json (stage "calibrate")
// summary.json: world_origin {latitude_deg, longitude_deg, height_m}, utm {zone, northern, epsg},
// inputs, mount, stages -> name -> {seconds, peak_rss_mb, counts...}.
#pragma once

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/calib/boresight.hpp"
#include "processor/georef/georef.hpp"
#include "processor/io/ingest.hpp"

namespace pitmap::proc::pipeline {

struct PipelineConfig {
    io::IngestConfig ingest;
    georef::GeorefConfig georef;
    calib::BoresightConfig calibrate;
    // World origin; NaN = the first INS position.
    double origin_latitude_deg = std::numeric_limits<double>::quiet_NaN();
    double origin_longitude_deg = std::numeric_limits<double>::quiet_NaN();
    double origin_height_m = std::numeric_limits<double>::quiet_NaN();
    bool write_las = true;        // points.las (UTM) beside points.ply
    std::string vehicle_yaml;     // "" = vehicle.yaml beside the first log

    std::vector<std::string> Validate() const;
};

// Reads a YAML config (sections ingest, georef, calibrate, products); every problem listed.
Expected<PipelineConfig> LoadConfig(const std::string& path);
// The YAML of every default, with a comment per key.
std::string DefaultsYaml();

using Log = std::function<void(const std::string&)>;

// `info`: a text report of the inputs (files, channels, counts, time spans).
Expected<std::string> Info(const std::vector<std::string>& inputs, const PipelineConfig& config);
Status RunGeorefStage(const std::vector<std::string>& inputs, const std::string& out_dir,
                      const PipelineConfig& config, const Log& log);
Status RunCalibrateStage(const std::string& out_dir, const PipelineConfig& config, const Log& log);

}  // namespace pitmap::proc::pipeline
