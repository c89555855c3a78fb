// SPDX-License-Identifier: MIT
// pitmap: the shore processor's command line. Arguments -> YAML -> Config -> Validate -> run.
//   pitmap info LOGS... [--config FILE] [--vehicle FILE] [--sonar-clock-offset S]
//   pitmap georef LOGS... --out P [--config FILE] [--vehicle FILE] [--from-raw]
//                 [--sonar-clock-offset S] [--svp FILE...]
//   pitmap calibrate --out P [--config FILE]
//   pitmap slam --out P [--config FILE]
//   pitmap grid --out P [--config FILE]
//   pitmap fuse --out P [--config FILE]
//   pitmap mesh --out P [--config FILE]
//   pitmap report --out P
//   pitmap run LOGS... --out P [--config FILE] [--vehicle FILE] [--from-raw]
//              [--sonar-clock-offset S] [--svp FILE...] [--no-calibrate] [--no-slam]
//   pitmap config --defaults | --vehicle
//   pitmap live ARGS...   runs pitmap-live ARGS... (live coverage, status, alarms, page)
//   pitmap edit P [--port N] [--no-open] [--config FILE]   the hand-editing page (processor/edit)
//   pitmap compare A B --out C [--dof 4|6] [--min-region-area M2] [--capacity-step M] [--no-3d]
//                  [--no-mesh] [--design D.tif] [--strict] [--no-report]
//   pitmap compare A --design D.tif --out C   one survey against a design surface
//   pitmap compare A B C... --out O (or one file listing the folders)   a series in time order
//                  two surveys of one site (processor/pipeline/compare_stage.hpp)
//   pitmap --version
// Stages take --strict: exit status 4 when a quality gate tripped (summary.json quality_gates).
// Every command with --out holds P/.pitmap.lock while it runs (processor/io/products_lock.hpp):
// a second command on the same P fails at once naming the first. Inputs are checked before P is
// created: a missing input or products folder creates nothing.
// Exit status (common/exit_codes.hpp, docs/cli.md): 0 ok, 1 run failure, 2 usage (unknown
// command or option, bad value, invalid config, missing input), 3 internal error, 4 --strict gate.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>
#include <filesystem>

#include "common/cli/parse.hpp"
#include "common/config.hpp"
#include "common/exit_codes.hpp"
#include "common/peak_memory.hpp"
#include "common/vehicle.hpp"
#include "processor/edit/edit_command.hpp"
#include "processor/io/products.hpp"
#include "processor/io/products_lock.hpp"
#include "processor/pipeline/compare_stage.hpp"
#include "processor/pipeline/pipeline.hpp"

namespace pp = pitmap::proc::pipeline;

namespace {

namespace codes = pitmap::exit_code;

int Fail(const std::string& message, int code = codes::kFailure) {
    std::fprintf(stderr, "pitmap: %s\n", message.c_str());
    return code;
}

// What a command reads must exist before anything is created (P and its lock among them): a
// typo in a path is a usage error that leaves nothing behind.
std::string MissingInput(const std::vector<std::string>& paths, const char* what) {
    for (const auto& p : paths) {
        std::error_code ec;
        if (!std::filesystem::exists(p, ec)) return std::string(what) + " " + p + " does not exist";
    }
    return "";
}

// pitmap-report and pitmap-live live beside the pitmap executable (build/bin, or the install's
// bin).
std::string SiblingProgram(const char* name) {
    std::error_code ec;
    const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (ec) return "";
    return (self.parent_path() / name).string();
}
std::string ReportProgram() {
    return SiblingProgram("pitmap-report");
}

// The quality gates summary.json records (processor/pipeline/internal.hpp), one line each.
std::vector<std::string> TrippedGates(const std::string& out_dir) {
    std::vector<std::string> out;
    auto j = pitmap::proc::io::ReadSummaryJson(out_dir + "/summary.json");
    if (!j || !j->is_object() || !j->contains("quality_gates")) return out;
    const auto& g = (*j)["quality_gates"];
    if (!g.is_array()) return out;
    for (const auto& e : g) {
        if (e.is_object()) out.push_back(e.value("stage", "?") + "/" + e.value("gate", "?"));
    }
    return out;
}

std::atomic<bool> g_stop{false};
extern "C" void OnSignal(int) {
    g_stop = true;
}

std::string CommandLine(int argc, char** argv) {
    std::string line;
    for (int i = 0; i < argc; ++i) line += (i > 0 ? " " : "") + std::string(argv[i]);
    return line;
}

// What the command line asked for: the options the commands share and each command's own.
struct Options {
    std::vector<std::string> inputs, svp_files;
    std::string out_dir, config_path, vehicle_path;
    bool from_raw = false, defaults = false, vehicle_template = false;
    double sonar_clock_offset_s = 0;
    bool offset_given = false;
    bool no_calibrate = false, no_slam = false, no_report = false, no_clean = false;
    bool strict = false;
    int edit_port = 8767;
    bool no_open = false;
    std::string rerun_program;
    std::string fuse_tile;  // fuse --tile I,J
    std::string grid_tile;  // grid --tile I,J
    bool grid_merge_tiles = false;
    bool list_tiles = false;  // grid or fuse --list-tiles
    bool merge_tiles = false;
    std::vector<std::string> compare_inputs;
    int compare_dof = 6;
    bool compare_no_3d = false;
    bool compare_no_mesh = false;
    pp::CompareConfig compare_config;
};

// The subcommands, to ask which one was given.
struct Commands {
    CLI::App *info, *geo, *cal, *slam, *clean, *grid, *fuse, *mesh, *report, *rerun, *run;
    CLI::App *edit, *compare, *cfg;
};

// The options of the commands that read the inputs (info, georef, run).
void AddInputOptions(CLI::App* sub, Options& o) {
    sub->add_option("--vehicle",
                    o.vehicle_path,
                    "vehicle.yaml (pitmap config --vehicle); default: vehicle.yaml beside "
                    "the first input");
    sub->add_option("--sonar-clock-offset",
                    o.sonar_clock_offset_s,
                    ".83P files: the sonar's (header) clock minus GPS-disciplined UTC, s. "
                    "Positive = the sonar clock runs ahead of UTC, negative = it runs behind "
                    "(a topside PC 2 s fast: 2); GPS time = header time - S + (GPS - UTC). "
                    "Default: the config's "
                    "ingest.sonar_clock_offset_s, else vehicle.yaml's sonar.clock_offset_s, "
                    "else found from the 83P headers")
        ->each([&o](const std::string&) { o.offset_given = true; });
}

// info, georef, the stage commands, rerun and run (a table of options).
void DeclareStageCommands(CLI::App& app, Options& o, Commands& c) {
    c.info = app.add_subcommand("info", "summarise logs and vendor files");
    c.info->add_option("inputs", o.inputs, "LCM logs, .83P, NovAtel files or folders")->required();
    AddInputOptions(c.info, o);
    c.info->add_option("--config",
                       o.config_path,
                       "YAML config (its ingest settings and products.origin, which the CRS line "
                       "follows)");
    c.geo = app.add_subcommand("georef", "ingest and georeference into a products folder");
    c.geo->add_option("inputs", o.inputs, "LCM logs, .83P, NovAtel files or folders")->required();
    c.geo->add_option("--out", o.out_dir, "products folder")->required();
    c.geo->add_option("--config", o.config_path, "YAML config (see pitmap config --defaults)");
    c.geo->add_flag(
        "--from-raw", o.from_raw, "re-decode the raw channels instead of the decoded ones");
    AddInputOptions(c.geo, o);
    c.cal = app.add_subcommand("calibrate", "boresight calibration on a georeferenced folder");
    c.cal->add_option("--out", o.out_dir, "products folder written by pitmap georef")->required();
    c.cal->add_option("--config", o.config_path, "YAML config");
    c.slam = app.add_subcommand("slam", "continuous-time SLAM on a georeferenced folder");
    c.clean = app.add_subcommand(
        "clean", "flag fish, bubbles, ghosts: the automatic 3D cleaning of the soundings");
    c.grid = app.add_subcommand(
        "grid", "per-sounding TPU and CUBE surface (dem.tif, dem.bag) of the current soundings");
    c.grid->add_option("--tile",
                       o.grid_tile,
                       "I,J: one DEM tile alone (config tiles:; P/tiles/dem/dem_I_J.tif; "
                       "negative indices as --tile=-1,2), then --merge-tiles");
    c.grid->add_flag(
        "--merge-tiles", o.grid_merge_tiles, "P/tiles/dem.vrt over the DEM tiles of --tile");
    c.grid->add_flag("--list-tiles",
                     o.list_tiles,
                     "print the survey's DEM tiles, one I,J a line (config tiles:)");
    c.fuse = app.add_subcommand("fuse", "TSDF fusion of the pings on the current trajectory");
    c.fuse->add_flag("--list-tiles",
                     o.list_tiles,
                     "print the survey's TSDF tiles, one I,J a line (config tiles:)");
    c.fuse->add_option("--tile",
                       o.fuse_tile,
                       "I,J: one TSDF tile alone (config tiles:; P/tiles/tsdf, P/tiles/mesh; "
                       "negative indices as --tile=-1,2), then --merge-tiles");
    c.fuse->add_flag("--merge-tiles",
                     o.merge_tiles,
                     "P/tsdf.vdb and P/tiles/mesh/index.json from the tiles of --tile");
    c.mesh = app.add_subcommand("mesh", "surface mesh from the folder's tsdf.vdb");
    c.report = app.add_subcommand("report", "report.html of a products folder");
    c.rerun = app.add_subcommand(
        "rerun",
        "the stages after georef again (calibrate, SLAM, clean, grid, TSDF, mesh, report) on a "
        "products folder, e.g. after pitmap edit");
    for (auto* sub : {c.slam, c.clean, c.grid, c.fuse, c.mesh, c.report, c.rerun}) {
        sub->add_option("--out", o.out_dir, "products folder")->required();
        sub->add_option("--config", o.config_path, "YAML config");
    }
    c.run = app.add_subcommand(
        "run", "everything: ingest, georef, calibrate, SLAM, clean, grid, TSDF, mesh, report");
    c.run->add_option("inputs", o.inputs, "LCM logs, .83P, NovAtel files or folders")->required();
    c.run->add_option("--out", o.out_dir, "products folder")->required();
    c.run->add_option("--config", o.config_path, "YAML config (see pitmap config --defaults)");
    c.run->add_flag(
        "--from-raw", o.from_raw, "re-decode the raw channels instead of the decoded ones");
    AddInputOptions(c.run, o);
    for (auto* sub : {c.run, c.rerun}) {
        sub->add_flag("--no-calibrate", o.no_calibrate, "keep the boresight of vehicle.yaml");
        sub->add_flag("--no-slam", o.no_slam, "fuse on the INS trajectory");
        sub->add_flag("--no-clean", o.no_clean, "no automatic cleaning of the soundings");
        sub->add_flag("--no-report", o.no_report, "no report.html");
    }
    // The commands that georeference take sound-velocity casts.
    for (auto* sub : {c.geo, c.run}) {
        sub->add_option("--svp",
                        o.svp_files,
                        "sound-velocity casts (CARIS .svp, CSV or two-column depth/speed): ray "
                        "trace every beam through them (config refraction.svp_files)");
    }
}

void DeclareEditCommand(CLI::App& app, Options& o, Commands& c) {
    c.edit = app.add_subcommand("edit", "review and edit soundings by hand on a local page");
    c.edit->add_option("P", o.out_dir, "products folder (survey.pitmap)")->required();
    c.edit->add_option("--port", o.edit_port, "port on 127.0.0.1 (0 = any free one)");
    c.edit->add_flag("--no-open", o.no_open, "only print the URL (do not start a browser)");
    c.edit->add_option("--config", o.config_path, "YAML config (the georeferencing's settings)");
    c.edit->add_option("--rerun-program", o.rerun_program, "(tests) what the re-run button starts")
        ->group("");
}

void DeclareCompareCommand(CLI::App& app, Options& o, Commands& c) {
    c.compare = app.add_subcommand(
        "compare",
        "two surveys of one site: co-registration on stable terrain, DEM of difference with a "
        "level of detection, change regions with volumes and uncertainty, capacity curves "
        "(docs/compare.md)");
    c.compare
        ->add_option("A B",
                     o.compare_inputs,
                     "products folders, the earlier survey first (one with --design: that survey "
                     "against the design alone; more than two, or one file listing them: a "
                     "series, each consecutive pair compared)")
        ->required()
        ->expected(1, -1);
    c.compare->add_option("--out", o.out_dir, "output folder for the comparison")->required();
    c.compare->add_option("--config",
                          o.config_path,
                          "the YAML config the surveys were processed with (pitmap run --config): "
                          "where their CUBE resolutions differ, the coarser survey is gridded "
                          "again with its georef, grid and vertical sections at the finer "
                          "resolution (default: the defaults)");
    c.compare
        ->add_option("--dof",
                     o.compare_dof,
                     "registration: 6 (translation, roll, pitch, yaw; default) or 4 (translation "
                     "and yaw)")
        ->check(CLI::IsMember({4, 6}));
    c.compare->add_option("--min-region-area",
                          o.compare_config.change.min_region_area_m2,
                          "m2: smaller change regions are not reported (0.5)");
    c.compare->add_flag("--no-3d",
                        o.compare_no_3d,
                        "no 3D change along the normal on the soundings (change_points.ply)");
    c.compare->add_option("--design",
                          o.compare_config.design_path,
                          "design surface (the planned cut: a GeoTIFF of heights, or a PLY mesh, "
                          "in the surveys' CRS and vertical datum): the volume between each "
                          "survey and it");
    c.compare->add_flag("--no-mesh",
                        o.compare_no_mesh,
                        "no change on B's TSDF mesh (change_mesh.ply, change_mesh.glb)");
    c.compare->add_option("--capacity-step",
                          o.compare_config.capacity_step_m,
                          "m: a row of the capacity curves every step (0.25)");
    c.compare->add_flag("--no-report",
                        o.no_report,
                        "no change report (C/report.html, written by pitmap-report --compare C "
                        "after a comparison of two surveys)");
}

Commands DeclareCommands(CLI::App& app, Options& o) {
    app.require_subcommand(1);
    // Run before parsing (main); here for --help and the did-you-mean of a mistyped command.
    app.add_subcommand("live",
                       "live coverage, status and alarms from the daemon's LCM channels or a "
                       "replayed log, on a local page (runs pitmap-live; pitmap live --help)")
        ->allow_extras()
        ->prefix_command();
    Commands c{};
    DeclareStageCommands(app, o, c);
    DeclareEditCommand(app, o, c);
    DeclareCompareCommand(app, o, c);
    c.cfg = app.add_subcommand("config", "configuration helpers");
    c.cfg->add_flag("--defaults", o.defaults, "print the YAML of every default");
    c.cfg->add_flag(
        "--vehicle", o.vehicle_template, "print the vehicle.yaml schema, as a template");
    for (auto* sub :
         {c.geo, c.cal, c.slam, c.clean, c.grid, c.fuse, c.mesh, c.run, c.rerun, c.compare}) {
        sub->add_flag("--strict",
                      o.strict,
                      "exit with status 4 when a quality gate trips (the stage could not "
                      "explain its data; the products are still written and say why)");
    }
    return c;
}

// Says the tripped gates; with --strict they are the exit status.
int GatesExit(std::size_t count, const std::string& which, bool strict) {
    if (count == 0) return 0;
    std::fprintf(stderr,
                 "pitmap: %zu quality gate(s) tripped: %s%s\n",
                 count,
                 which.c_str(),
                 strict ? "" : "; --strict makes this an error");
    return strict ? codes::kQualityGate : 0;
}

int RunConfigCommand(const Options& o) {
    if (o.defaults == o.vehicle_template) {
        return Fail("config: give --defaults or --vehicle", codes::kUsage);
    }
    std::fputs((o.defaults ? pp::DefaultsYaml() : pitmap::VehicleYamlTemplate()).c_str(), stdout);
    return 0;
}

int RunCompareCommand(Options& o, const std::string& command_line) {
    // Both folders must be there before C is created.
    if (auto m = MissingInput(o.compare_inputs, "products folder"); !m.empty())
        return Fail(m + "; nothing written", codes::kUsage);
    o.compare_config.registration.estimate_roll_pitch = o.compare_dof == 6;
    o.compare_config.change3d = !o.compare_no_3d;
    o.compare_config.change_mesh = !o.compare_no_mesh;
    if (auto problems = o.compare_config.Validate(); !problems.empty())
        return Fail("compare: " + pitmap::FormatProblems(problems), codes::kUsage);
    if (!o.config_path.empty()) {
        if (auto m = MissingInput({o.config_path}, "config"); !m.empty())
            return Fail(m + "; nothing written", codes::kUsage);
        auto config = pp::LoadConfig(o.config_path);
        if (!config) return Fail("compare: " + config.error().message, codes::kUsage);
        if (auto problems = config->Validate(); !problems.empty())
            return Fail("compare: invalid config:\n" + pitmap::FormatProblems(problems),
                        codes::kUsage);
        o.compare_config.survey = *config;
    }
    const bool list_file =
        o.compare_inputs.size() == 1 && std::filesystem::is_regular_file(o.compare_inputs.front());
    if (o.compare_inputs.size() < 2 && o.compare_config.design_path.empty() && !list_file)
        return Fail(
            "compare: two products folders (or more, or a file listing them), or one and a "
            "design surface (--design)",
            codes::kUsage);
    if (!o.compare_config.design_path.empty()) {
        if (auto m = MissingInput({o.compare_config.design_path}, "design surface"); !m.empty())
            return Fail(m + "; nothing written", codes::kUsage);
    }
    auto lock = pitmap::proc::io::ProductsLock::Acquire(o.out_dir, command_line);
    if (!lock) return Fail(lock.error().message);
    const auto log = [](const std::string& m) { std::fprintf(stderr, "pitmap: %s\n", m.c_str()); };
    if (o.compare_inputs.size() > 2 || list_file) {
        auto gates = pp::RunCompareSeries(o.compare_inputs, o.out_dir, o.compare_config, log);
        if (!gates) return Fail(gates.error().message);
        return GatesExit(
            static_cast<std::size_t>(*gates), "see each interval's compare.json", o.strict);
    }
    auto gates = pp::RunCompare(o.compare_inputs[0],
                                o.compare_inputs.size() > 1 ? o.compare_inputs[1] : std::string(),
                                o.out_dir,
                                o.compare_config,
                                log);
    if (!gates) return Fail(gates.error().message);
    // The change report of two surveys (a survey against a design alone has none).
    if (!o.no_report && o.compare_inputs.size() > 1) {
        if (auto st = pp::WriteCompareReport(o.out_dir, ReportProgram(), log); !st)
            return Fail(st.error().message);
    }
    return GatesExit(static_cast<std::size_t>(*gates), "see compare.json quality_gates", o.strict);
}

// The config file with the command line's overrides, validated; every problem listed.
pitmap::Expected<pp::PipelineConfig> PipelineConfigOf(const Options& o) {
    pp::PipelineConfig config;
    if (!o.config_path.empty()) {
        if (auto m = MissingInput({o.config_path}, "config"); !m.empty()) return pitmap::Error{m};
        auto c = pp::LoadConfig(o.config_path);
        if (!c) return c.error();
        config = *c;
    }
    if (o.from_raw) config.ingest.source = pitmap::proc::io::IngestSource::kRaw;
    if (o.offset_given) {
        config.ingest.sonar_clock_offset_s = o.sonar_clock_offset_s;
        config.ingest.sonar_clock_offset_known = true;
    }
    if (!o.vehicle_path.empty()) config.vehicle_yaml = o.vehicle_path;
    if (!o.svp_files.empty()) config.refraction.svp_files = o.svp_files;
    if (o.no_calibrate) config.run.calibrate = false;
    if (o.no_slam) config.run.slam = false;
    if (o.no_report) config.run.report = false;
    if (o.no_clean) config.clean.enabled = false;
    config.report_program = ReportProgram();
    if (auto problems = config.Validate(); !problems.empty()) {
        return pitmap::Error{"invalid config:\n" + pitmap::FormatProblems(problems)};
    }
    return config;
}

// The first input the command reads that is not there ("" when all are).
std::string FirstMissingInput(const Options& o, const Commands& c) {
    std::string missing = MissingInput(o.inputs, "input");
    if (missing.empty() && !o.vehicle_path.empty())
        missing = MissingInput({o.vehicle_path}, "vehicle file");
    if (missing.empty()) missing = MissingInput(o.svp_files, "sound-velocity file");
    // The stages after georef read P itself: it must be there already.
    if (missing.empty() && !(c.info->parsed() || c.geo->parsed() || c.run->parsed())) {
        missing = MissingInput({o.out_dir}, "products folder");
        if (!missing.empty()) missing += " (pitmap georef or pitmap run writes it)";
    }
    return missing;
}

int RunEditCommand(const Options& o, const pp::PipelineConfig& config) {
    // No lock on P: the page's re-run (pitmap rerun P) takes it.
    namespace pe = pitmap::proc::edit;
    pe::EditCommand e;
    e.out_dir = o.out_dir;
    e.session.georef = config.georef;
    e.session.tpu_sound_speed_mps = config.grid.tpu_sound_speed_mps;
    e.session.ins_sigma_max_age_s = config.grid.ins_sigma_max_age_s;
    e.server.port = o.edit_port;
    e.server.rerun_program = o.rerun_program.empty() ? SiblingProgram("pitmap") : o.rerun_program;
    e.open_browser = !o.no_open;
    std::signal(SIGINT, OnSignal);
    std::signal(SIGTERM, OnSignal);
    return pe::RunEditCommand(e, [] { return g_stop.load(); });
}

int RunInfoCommand(const Options& o, const pp::PipelineConfig& config) {
    auto text = pp::Info(o.inputs, config);
    if (!text) return Fail(text.error().message);
    std::fputs(text->c_str(), stdout);
    return 0;
}

// --tile I,J of `command`.
pitmap::Expected<pp::TileIndex> ParseTile(const std::string& command, const std::string& text) {
    char rest = 0;
    long long i = 0, j = 0;
    if (std::sscanf(text.c_str(), "%lld,%lld%c", &i, &j, &rest) != 2) {
        return pitmap::Error{command + ": --tile " + text + ": expected I,J (two integers)"};
    }
    return pp::TileIndex{i, j};
}

// --list-tiles: the survey's tiles of the grid or the TSDF on stdout, one "I,J" a line.
pitmap::Status PrintTiles(const Options& o,
                          const pp::PipelineConfig& config,
                          pp::Stage stage,
                          const pp::Log& log) {
    auto tiles = pp::ListTiles(o.out_dir, config, stage, log);
    if (!tiles) return tiles.error();
    for (const pp::TileIndex& t : *tiles)
        std::printf("%lld,%lld\n", static_cast<long long>(t.i), static_cast<long long>(t.j));
    return pitmap::Ok{};
}

// `pitmap fuse`, of the whole survey, one tile (--tile I,J) or the merge of the tiles.
pitmap::Status RunFuseCommand(const Options& o,
                              const pp::PipelineConfig& config,
                              const pp::Log& log) {
    if (o.fuse_tile.empty() && !o.merge_tiles && !o.list_tiles)
        return pp::RunFuseStage(o.out_dir, config, log);
    if (!config.tiles.enabled)
        return pitmap::Error{"fuse: --tile, --merge-tiles and --list-tiles need tiles.enabled"};
    if (o.list_tiles) return PrintTiles(o, config, pp::Stage::kFuse, log);
    if (o.merge_tiles && !o.fuse_tile.empty())
        return pitmap::Error{"fuse: --tile and --merge-tiles are two steps: give one of them"};
    if (o.merge_tiles) return pp::RunMergeFuseTiles(o.out_dir, config, log);
    auto t = ParseTile("fuse", o.fuse_tile);
    if (!t) return t.error();
    return pp::RunFuseTile(o.out_dir, config, *t, log);
}

// `pitmap grid`, of the whole survey or one tile (--tile I,J).
pitmap::Status RunGridCommand(const Options& o,
                              const pp::PipelineConfig& config,
                              const pp::Log& log) {
    if (o.grid_tile.empty() && !o.grid_merge_tiles && !o.list_tiles)
        return pp::RunGridStage(o.out_dir, config, log);
    if (!config.tiles.enabled)
        return pitmap::Error{"grid: --tile, --merge-tiles and --list-tiles need tiles.enabled"};
    if (static_cast<int>(!o.grid_tile.empty()) + o.grid_merge_tiles + o.list_tiles > 1)
        return pitmap::Error{"grid: --tile, --merge-tiles and --list-tiles: give one of them"};
    if (o.list_tiles) return PrintTiles(o, config, pp::Stage::kGrid, log);
    if (o.grid_merge_tiles) return pp::RunMergeGridTiles(o.out_dir, config, log);
    auto t = ParseTile("grid", o.grid_tile);
    if (!t) return t.error();
    return pp::RunGridTile(o.out_dir, config, *t, log);
}

// georef, a stage, rerun or run on P, holding P's lock; the gates the stages tripped.
int RunStageCommand(const Commands& c,
                    const Options& o,
                    const pp::PipelineConfig& config,
                    const std::string& command_line) {
    // One command at a time on P; creating P and its lock file is also the check that P can be
    // written, before any work.
    // The per-tile commands share it with each other (each writes only its tile's files).
    const bool tile_job =
        (c.grid->parsed() && (!o.grid_tile.empty() || o.list_tiles) && !o.grid_merge_tiles) ||
        (c.fuse->parsed() && (!o.fuse_tile.empty() || o.list_tiles) && !o.merge_tiles);
    auto lock = pitmap::proc::io::ProductsLock::Acquire(
        o.out_dir,
        command_line,
        tile_job ? pitmap::proc::io::LockMode::kShared : pitmap::proc::io::LockMode::kExclusive);
    if (!lock) return Fail(lock.error().message);
    const pp::Log log = [](const std::string& m) {
        std::fprintf(stderr, "pitmap: %s\n", m.c_str());
    };
    const std::string& P = o.out_dir;
    pitmap::Status status = pitmap::Ok{};
    if (c.geo->parsed()) status = pp::RunGeorefStage(o.inputs, P, config, log);
    if (c.cal->parsed()) status = pp::RunCalibrateStage(P, config, log);
    if (c.slam->parsed()) status = pp::RunSlamStage(P, config, log);
    if (c.clean->parsed()) status = pp::RunCleanStage(P, config, log);
    if (c.rerun->parsed()) status = pp::RunFromSurvey(P, config, log);
    if (c.grid->parsed()) status = RunGridCommand(o, config, log);
    if (c.fuse->parsed()) status = RunFuseCommand(o, config, log);
    if (c.mesh->parsed()) status = pp::RunMeshStage(P, config, log);
    if (c.report->parsed()) status = pp::RunReportStage(P, config, log);
    if (c.run->parsed()) status = pp::RunAll(o.inputs, P, config, log);
    if (!status) return Fail(status.error().message);
    const auto gates = TrippedGates(P);
    std::string list;
    for (const auto& g : gates) list += (list.empty() ? "" : ", ") + g;
    return GatesExit(gates.size(), list + " (summary.json quality_gates)", o.strict);
}

}  // namespace

int main(int argc, char** argv) try {
    // Large arrays on transparent huge pages (re-executes once; see common/peak_memory.hpp).
    pitmap::ReexecWithHugePageMalloc(argv);
    // `pitmap live ARGS` is pitmap-live ARGS (its own program: it links the HTTP server).
    if (argc >= 2 && std::string(argv[1]) == "live") {
        const std::string live = SiblingProgram("pitmap-live");
        argv[1] = const_cast<char*>(live.c_str());
        ::execv(live.c_str(), argv + 1);
        return Fail("cannot run " + live + " (build the pitmap-live target)");
    }
    CLI::App app{"pitmap: flooded open-pit mine mapping, shore-side processor"};
    Options o;
    const Commands c = DeclareCommands(app, o);
    if (auto code = pitmap::cli::ParseCommandLine(app, argc, argv, "pitmap")) return *code;
    const std::string command_line = CommandLine(argc, argv);

    if (c.cfg->parsed()) return RunConfigCommand(o);
    if (c.compare->parsed()) return RunCompareCommand(o, command_line);
    const auto config = PipelineConfigOf(o);
    if (!config) return Fail(config.error().message, codes::kUsage);
    if (const std::string missing = FirstMissingInput(o, c); !missing.empty()) {
        return Fail(missing + (o.out_dir.empty() ? "" : "; nothing written"), codes::kUsage);
    }
    if (c.edit->parsed()) return RunEditCommand(o, *config);
    if (c.info->parsed()) return RunInfoCommand(o, *config);
    return RunStageCommand(c, o, *config, command_line);
} catch (const std::exception& e) {
    std::fprintf(stderr, "pitmap: internal error: %s\n", e.what());
    return codes::kInternal;
}
