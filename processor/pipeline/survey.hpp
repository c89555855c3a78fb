// SPDX-License-Identifier: MIT
// Internal to processor/pipeline: the in-memory survey the stages pass along, and what the
// stage implementations share (summary bookkeeping, per-stage time and memory).
#pragma once

#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "processor/fusion/tsdf.hpp"
#include "processor/georef/georef.hpp"
#include "processor/io/ingest.hpp"
#include "processor/pipeline/pipeline.hpp"

namespace pitmap::proc::pipeline::detail {

// What a products folder holds, in memory: the ingested series, the mount, the world origin,
// the georeferenced soundings on the current trajectory, and summary.json.
struct Survey {
    std::string out_dir;
    io::IngestResult ingest;
    georef::SonarMount mount;
    Geodetic origin;
    georef::GeorefResult geo;
    nlohmann::json summary;
    std::shared_ptr<const svp::Refraction> refraction;  // null = straight rays
};

// Refraction for a new georeference: the config's casts (none: straight rays, and
// summary["refraction"] is removed) with the INS height above the water line from the config,
// else from the vehicle file; records summary["refraction"]. An unreadable or bad cast file,
// or no INS height, is an error.
Status SetUpRefraction(Survey& s,
                       const PipelineConfig& config,
                       std::optional<double> vehicle_ins_height_m,
                       const Log& log);
// Refraction for a later stage: what summary["refraction"] recorded (the casts are read again).
Status RestoreRefraction(Survey& s, const Log& log);

// Loads P/summary.json and P/ingest.cache and georeferences with the recorded mount; with
// `apply_trajectory`, moves the pings onto P/trajectory.csv when a SLAM stage wrote it.
Expected<Survey> LoadSurvey(const std::string& out_dir,
                            const PipelineConfig& config,
                            bool apply_trajectory,
                            const Log& log);

// Wall time of one stage. Construction resets the resident-memory high-water mark
// (common/peak_memory.hpp ResetPeakRss), so RecordStage's peak_rss_mb (PeakRssMb) is the
// stage's own peak where the kernel allows it and the process's peak so far otherwise.
class StageClock {
public:
    StageClock();
    double seconds() const;

private:
    std::chrono::steady_clock::time_point start_;
};

// Records a stage in summary["stages"][name] (adding seconds and peak_rss_mb) and in
// summary["stage_order"].
void RecordStage(nlohmann::json& summary,
                 Stage name,
                 nlohmann::json stage,
                 const StageClock& clock);

nlohmann::json MountJson(const georef::SonarMount& m);
Expected<georef::SonarMount> MountFromJson(const nlohmann::json& m);
// summary["world_origin"] {latitude_deg, longitude_deg, height_m}; an error names what is wrong.
Expected<Geodetic> OriginFromJson(const nlohmann::json& summary);

// points.ply, points.las (when configured) and summary["utm"] for the current soundings.
Status WritePoints(const std::string& dir,
                   const georef::GeorefResult& geo,
                   const PipelineConfig& c,
                   nlohmann::json& summary);

Status SaveSummary(const Survey& s);

// Quality gates (QualityConfig): a stage that cannot explain its data says so in the terminal
// ("quality gate STAGE/GATE: ...") and in summary["quality_gates"] [{stage, gate, message}];
// the report lists them. A stage clears its own before it runs again.
void TripGate(
    Survey& s, Stage stage, const std::string& gate, const std::string& message, const Log& log);
void ClearGates(Survey& s, Stage stage);

// The sonar clock after ingest: for .83P pings (topside clock) the coarse offset from the
// header aids is found and applied, or a configured offset is checked against it; then the
// navigation and sonar spans must overlap. summary["sonar_clock"] records what was done.
Status ClockSurvey(Survey& s, const PipelineConfig& config, const Log& log);

// The stages on a survey in memory (bodies of the Run*Stage functions and of RunAll).
Status GeorefSurvey(Survey& s,
                    const std::vector<std::string>& inputs,
                    const PipelineConfig& config,
                    const Log& log);
Status CalibrateSurvey(Survey& s, const PipelineConfig& config, const Log& log);
Status SlamSurvey(Survey& s, const PipelineConfig& config, const Log& log);
// Per-sounding TPU and the CUBE surface (grid_stage.hpp).
Status GridSurvey(Survey& s, const PipelineConfig& config, const Log& log);
// Integrates the pings on the current trajectory, applies the weight filter; `stage` is kFuse,
// or kFuseInitial for the mesh before SLAM.
Expected<fusion::TsdfVolume> FuseSurvey(Survey& s,
                                        const PipelineConfig& config,
                                        Stage stage,
                                        const Log& log);
// Meshes a volume; kMesh writes mesh.* and mesh_filled.*, kMeshInitial only mesh_initial.ply.
Status MeshSurvey(Survey& s,
                  const fusion::TsdfVolume& volume,
                  const PipelineConfig& config,
                  Stage stage,
                  const Log& log);
Status ReportSurvey(Survey& s, const PipelineConfig& config, const Log& log);

}  // namespace pitmap::proc::pipeline::detail
