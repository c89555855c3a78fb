// SPDX-License-Identifier: MIT
// pitmap: the shore processor's command line. Arguments -> YAML -> Config -> Validate -> run.
//   pitmap info LOGS...
//   pitmap georef LOGS... --out P [--config FILE] [--from-raw] [--sonar-clock-offset S]
//   pitmap calibrate --out P [--config FILE]
//   pitmap config --defaults
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "common/config.hpp"
#include "processor/pipeline/pipeline.hpp"

namespace pp = pitmap::proc::pipeline;

namespace {

int Fail(const std::string& message) {
    std::fprintf(stderr, "pitmap: %s\n", message.c_str());
    return 1;
}

}  // namespace

int main(int argc, char** argv) try {
    CLI::App app{"pitmap: flooded open-pit mine mapping, shore-side processor"};
    app.require_subcommand(1);
    std::vector<std::string> inputs;
    std::string out_dir, config_path;
    bool from_raw = false, defaults = false;
    double sonar_clock_offset_s = 0;
    bool offset_given = false;

    auto* info = app.add_subcommand("info", "summarise logs and vendor files");
    info->add_option("inputs", inputs, "LCM logs, .83P, NovAtel files or folders")->required();
    auto* geo = app.add_subcommand("georef", "ingest and georeference into a products folder");
    geo->add_option("inputs", inputs, "LCM logs, .83P, NovAtel files or folders")->required();
    geo->add_option("--out", out_dir, "products folder")->required();
    geo->add_option("--config", config_path, "YAML config (see pitmap config --defaults)");
    geo->add_flag("--from-raw", from_raw, "re-decode the raw channels instead of the decoded ones");
    geo->add_option("--sonar-clock-offset", sonar_clock_offset_s,
                    ".83P files: seconds added to the topside clock to get GPS time")
        ->each([&](const std::string&) { offset_given = true; });
    auto* cal = app.add_subcommand("calibrate", "boresight calibration on a georeferenced folder");
    cal->add_option("--out", out_dir, "products folder written by pitmap georef")->required();
    cal->add_option("--config", config_path, "YAML config");
    auto* cfg = app.add_subcommand("config", "configuration helpers");
    cfg->add_flag("--defaults", defaults, "print the YAML of every default");
    CLI11_PARSE(app, argc, argv);

    if (cfg->parsed()) {
        if (!defaults) return Fail("config: give --defaults");
        std::fputs(pp::DefaultsYaml().c_str(), stdout);
        return 0;
    }
    pp::PipelineConfig config;
    if (!config_path.empty()) {
        auto c = pp::LoadConfig(config_path);
        if (!c) return Fail(c.error().message);
        config = *c;
    }
    if (from_raw) config.ingest.source = pitmap::proc::io::IngestSource::kRaw;
    if (offset_given) config.ingest.sonar_clock_offset_s = sonar_clock_offset_s;
    if (auto problems = config.Validate(); !problems.empty()) {
        return Fail("invalid config:\n" + pitmap::FormatProblems(problems));
    }
    const pp::Log log = [](const std::string& m) { std::fprintf(stderr, "pitmap: %s\n", m.c_str()); };
    if (info->parsed()) {
        auto text = pp::Info(inputs, config);
        if (!text) return Fail(text.error().message);
        std::fputs(text->c_str(), stdout);
        return 0;
    }
    if (geo->parsed()) {
        if (auto s = pp::RunGeorefStage(inputs, out_dir, config, log); !s) return Fail(s.error().message);
        return 0;
    }
    if (auto s = pp::RunCalibrateStage(out_dir, config, log); !s) return Fail(s.error().message);
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "pitmap: internal error: %s\n", e.what());
    return 3;
}
