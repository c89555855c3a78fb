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
//                  [--strict]
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
    app.require_subcommand(1);
    // Run before parsing (above); here for --help and the did-you-mean of a mistyped command.
    app.add_subcommand("live",
                       "live coverage, status and alarms from the daemon's LCM channels or a "
                       "replayed log, on a local page (runs pitmap-live; pitmap live --help)")
        ->allow_extras()
        ->prefix_command();
    std::vector<std::string> inputs, svp_files;
    std::string out_dir, config_path, vehicle_path;
    bool from_raw = false, defaults = false, vehicle_template = false;
    double sonar_clock_offset_s = 0;
    bool offset_given = false;
    // The options of the commands that read the inputs (info, georef, run).
    const auto input_options = [&](CLI::App* sub) {
        sub->add_option("--vehicle",
                        vehicle_path,
                        "vehicle.yaml (pitmap config --vehicle); default: vehicle.yaml beside "
                        "the first input");
        sub->add_option("--sonar-clock-offset",
                        sonar_clock_offset_s,
                        ".83P files: the sonar's (header) clock minus GPS-disciplined UTC, s. "
                        "Positive = the sonar clock runs ahead of UTC, negative = it runs behind "
                        "(a topside PC 2 s fast: 2); GPS time = header time - S + (GPS - UTC). "
                        "Default: the config's "
                        "ingest.sonar_clock_offset_s, else vehicle.yaml's sonar.clock_offset_s, "
                        "else found from the 83P headers")
            ->each([&](const std::string&) { offset_given = true; });
    };

    auto* info = app.add_subcommand("info", "summarise logs and vendor files");
    info->add_option("inputs", inputs, "LCM logs, .83P, NovAtel files or folders")->required();
    input_options(info);
    info->add_option("--config",
                     config_path,
                     "YAML config (its ingest settings and products.origin, which the CRS line "
                     "follows)");
    auto* geo = app.add_subcommand("georef", "ingest and georeference into a products folder");
    geo->add_option("inputs", inputs, "LCM logs, .83P, NovAtel files or folders")->required();
    geo->add_option("--out", out_dir, "products folder")->required();
    geo->add_option("--config", config_path, "YAML config (see pitmap config --defaults)");
    geo->add_flag("--from-raw", from_raw, "re-decode the raw channels instead of the decoded ones");
    input_options(geo);
    auto* cal = app.add_subcommand("calibrate", "boresight calibration on a georeferenced folder");
    cal->add_option("--out", out_dir, "products folder written by pitmap georef")->required();
    cal->add_option("--config", config_path, "YAML config");
    auto* slam = app.add_subcommand("slam", "continuous-time SLAM on a georeferenced folder");
    auto* clean = app.add_subcommand(
        "clean", "flag fish, bubbles, ghosts: the automatic 3D cleaning of the soundings");
    auto* grid = app.add_subcommand(
        "grid", "per-sounding TPU and CUBE surface (dem.tif, dem.bag) of the current soundings");
    auto* fuse = app.add_subcommand("fuse", "TSDF fusion of the pings on the current trajectory");
    auto* mesh = app.add_subcommand("mesh", "surface mesh from the folder's tsdf.vdb");
    auto* report = app.add_subcommand("report", "report.html of a products folder");
    auto* rerun = app.add_subcommand(
        "rerun",
        "the stages after georef again (calibrate, SLAM, clean, grid, TSDF, mesh, report) on a "
        "products folder, e.g. after pitmap edit");
    for (auto* sub : {slam, clean, grid, fuse, mesh, report, rerun}) {
        sub->add_option("--out", out_dir, "products folder")->required();
        sub->add_option("--config", config_path, "YAML config");
    }
    bool no_calibrate = false, no_slam = false, no_report = false, no_clean = false;
    auto* run = app.add_subcommand(
        "run", "everything: ingest, georef, calibrate, SLAM, clean, grid, TSDF, mesh, report");
    run->add_option("inputs", inputs, "LCM logs, .83P, NovAtel files or folders")->required();
    run->add_option("--out", out_dir, "products folder")->required();
    run->add_option("--config", config_path, "YAML config (see pitmap config --defaults)");
    run->add_flag("--from-raw", from_raw, "re-decode the raw channels instead of the decoded ones");
    input_options(run);
    for (auto* sub : {run, rerun}) {
        sub->add_flag("--no-calibrate", no_calibrate, "keep the boresight of vehicle.yaml");
        sub->add_flag("--no-slam", no_slam, "fuse on the INS trajectory");
        sub->add_flag("--no-clean", no_clean, "no automatic cleaning of the soundings");
        sub->add_flag("--no-report", no_report, "no report.html");
    }
    // The commands that georeference take sound-velocity casts.
    for (auto* sub : {geo, run}) {
        sub->add_option("--svp",
                        svp_files,
                        "sound-velocity casts (CARIS .svp, CSV or two-column depth/speed): ray "
                        "trace every beam through them (config refraction.svp_files)");
    }
    int edit_port = 8767;
    bool no_open = false;
    auto* edit = app.add_subcommand("edit", "review and edit soundings by hand on a local page");
    edit->add_option("P", out_dir, "products folder (survey.pitmap)")->required();
    edit->add_option("--port", edit_port, "port on 127.0.0.1 (0 = any free one)");
    edit->add_flag("--no-open", no_open, "only print the URL (do not start a browser)");
    edit->add_option("--config", config_path, "YAML config (the georeferencing's settings)");
    std::string rerun_program;
    edit->add_option("--rerun-program", rerun_program, "(tests) what the re-run button starts")
        ->group("");
    std::vector<std::string> compare_inputs;
    int compare_dof = 6;
    pp::CompareConfig compare_config;
    auto* compare = app.add_subcommand(
        "compare",
        "two surveys of one site: co-registration on stable terrain, DEM of difference with a "
        "level of detection, change regions with volumes and uncertainty, capacity curves "
        "(docs/compare.md)");
    compare->add_option("A B", compare_inputs, "products folders, the earlier survey first")
        ->required()
        ->expected(2);
    compare->add_option("--out", out_dir, "output folder for the comparison")->required();
    compare
        ->add_option("--dof",
                     compare_dof,
                     "registration: 6 (translation, roll, pitch, yaw; default) or 4 (translation "
                     "and yaw)")
        ->check(CLI::IsMember({4, 6}));
    compare->add_option("--min-region-area",
                        compare_config.change.min_region_area_m2,
                        "m2: smaller change regions are not reported (0.5)");
    bool compare_no_3d = false;
    compare->add_flag("--no-3d",
                      compare_no_3d,
                      "no 3D change along the normal on the soundings (change_points.ply)");
    compare->add_option("--capacity-step",
                        compare_config.capacity_step_m,
                        "m: a row of the capacity curves every step (0.25)");
    auto* cfg = app.add_subcommand("config", "configuration helpers");
    cfg->add_flag("--defaults", defaults, "print the YAML of every default");
    cfg->add_flag("--vehicle", vehicle_template, "print the vehicle.yaml schema, as a template");
    bool strict = false;
    for (auto* sub : {geo, cal, slam, clean, grid, fuse, mesh, run, rerun, compare}) {
        sub->add_flag("--strict",
                      strict,
                      "exit with status 4 when a quality gate trips (the stage could not "
                      "explain its data; the products are still written and say why)");
    }
    if (auto code = pitmap::cli::ParseCommandLine(app, argc, argv, "pitmap")) return *code;

    if (cfg->parsed()) {
        if (defaults == vehicle_template) {
            return Fail("config: give --defaults or --vehicle", codes::kUsage);
        }
        std::fputs((defaults ? pp::DefaultsYaml() : pitmap::VehicleYamlTemplate()).c_str(), stdout);
        return 0;
    }
    if (compare->parsed()) {
        // Both folders must be there before C is created.
        if (auto m = MissingInput(compare_inputs, "products folder"); !m.empty())
            return Fail(m + "; nothing written", codes::kUsage);
        compare_config.registration.estimate_roll_pitch = compare_dof == 6;
        compare_config.change3d = !compare_no_3d;
        if (auto problems = compare_config.Validate(); !problems.empty())
            return Fail("compare: " + pitmap::FormatProblems(problems), codes::kUsage);
        std::string command_line;
        for (int i = 0; i < argc; ++i) command_line += (i > 0 ? " " : "") + std::string(argv[i]);
        auto lock = pitmap::proc::io::ProductsLock::Acquire(out_dir, command_line);
        if (!lock) return Fail(lock.error().message);
        auto gates = pp::RunCompare(
            compare_inputs[0],
            compare_inputs[1],
            out_dir,
            compare_config,
            [](const std::string& m) { std::fprintf(stderr, "pitmap: %s\n", m.c_str()); });
        if (!gates) return Fail(gates.error().message);
        if (*gates > 0) {
            std::fprintf(stderr,
                         "pitmap: compare: %d quality gate(s) tripped (compare.json "
                         "quality_gates)%s\n",
                         *gates,
                         strict ? "" : "; --strict makes this an error");
            if (strict) return codes::kQualityGate;
        }
        return 0;
    }
    pp::PipelineConfig config;
    if (!config_path.empty()) {
        if (auto m = MissingInput({config_path}, "config"); !m.empty()) {
            return Fail(m, codes::kUsage);
        }
        auto c = pp::LoadConfig(config_path);
        if (!c) return Fail(c.error().message, codes::kUsage);
        config = *c;
    }
    if (from_raw) config.ingest.source = pitmap::proc::io::IngestSource::kRaw;
    if (offset_given) {
        config.ingest.sonar_clock_offset_s = sonar_clock_offset_s;
        config.ingest.sonar_clock_offset_known = true;
    }
    if (!vehicle_path.empty()) config.vehicle_yaml = vehicle_path;
    if (!svp_files.empty()) config.refraction.svp_files = svp_files;
    if (no_calibrate) config.run.calibrate = false;
    if (no_slam) config.run.slam = false;
    if (no_report) config.run.report = false;
    if (no_clean) config.clean.enabled = false;
    config.report_program = ReportProgram();
    if (auto problems = config.Validate(); !problems.empty()) {
        return Fail("invalid config:\n" + pitmap::FormatProblems(problems), codes::kUsage);
    }
    {
        std::string missing = MissingInput(inputs, "input");
        if (missing.empty() && !vehicle_path.empty())
            missing = MissingInput({vehicle_path}, "vehicle file");
        if (missing.empty()) missing = MissingInput(svp_files, "sound-velocity file");
        // The stages after georef read P itself: it must be there already.
        if (missing.empty() && !(info->parsed() || geo->parsed() || run->parsed())) {
            missing = MissingInput({out_dir}, "products folder");
            if (!missing.empty()) missing += " (pitmap georef or pitmap run writes it)";
        }
        if (!missing.empty()) {
            return Fail(missing + (out_dir.empty() ? "" : "; nothing written"), codes::kUsage);
        }
    }
    const pp::Log log = [](const std::string& m) {
        std::fprintf(stderr, "pitmap: %s\n", m.c_str());
    };
    if (edit->parsed()) {
        // No lock on P: the page's re-run (pitmap rerun P) takes it.
        namespace pe = pitmap::proc::edit;
        pe::EditCommand e;
        e.out_dir = out_dir;
        e.session.georef = config.georef;
        e.session.tpu_sound_speed_mps = config.grid.tpu_sound_speed_mps;
        e.session.ins_sigma_max_age_s = config.grid.ins_sigma_max_age_s;
        e.server.port = edit_port;
        e.server.rerun_program = rerun_program.empty() ? SiblingProgram("pitmap") : rerun_program;
        e.open_browser = !no_open;
        std::signal(SIGINT, OnSignal);
        std::signal(SIGTERM, OnSignal);
        return pe::RunEditCommand(e, [] { return g_stop.load(); });
    }
    if (info->parsed()) {
        auto text = pp::Info(inputs, config);
        if (!text) return Fail(text.error().message);
        std::fputs(text->c_str(), stdout);
        return 0;
    }
    // One command at a time on P; creating P and its lock file is also the check that P can be
    // written, before any work.
    std::string command_line;
    for (int i = 0; i < argc; ++i) command_line += (i > 0 ? " " : "") + std::string(argv[i]);
    auto lock = pitmap::proc::io::ProductsLock::Acquire(out_dir, command_line);
    if (!lock) return Fail(lock.error().message);
    pitmap::Status status = pitmap::Ok{};
    if (geo->parsed()) status = pp::RunGeorefStage(inputs, out_dir, config, log);
    if (cal->parsed()) status = pp::RunCalibrateStage(out_dir, config, log);
    if (slam->parsed()) status = pp::RunSlamStage(out_dir, config, log);
    if (clean->parsed()) status = pp::RunCleanStage(out_dir, config, log);
    if (rerun->parsed()) status = pp::RunFromSurvey(out_dir, config, log);
    if (grid->parsed()) status = pp::RunGridStage(out_dir, config, log);
    if (fuse->parsed()) status = pp::RunFuseStage(out_dir, config, log);
    if (mesh->parsed()) status = pp::RunMeshStage(out_dir, config, log);
    if (report->parsed()) status = pp::RunReportStage(out_dir, config, log);
    if (run->parsed()) status = pp::RunAll(inputs, out_dir, config, log);
    if (!status) return Fail(status.error().message);
    if (const auto gates = TrippedGates(out_dir); !gates.empty()) {
        std::string list;
        for (const auto& g : gates) list += (list.empty() ? "" : ", ") + g;
        std::fprintf(stderr,
                     "pitmap: %zu quality gate(s) tripped: %s (summary.json quality_gates)%s\n",
                     gates.size(),
                     list.c_str(),
                     strict ? "" : "; --strict makes this an error");
        if (strict) return codes::kQualityGate;
    }
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "pitmap: internal error: %s\n", e.what());
    return codes::kInternal;
}
