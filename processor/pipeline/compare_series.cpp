// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "processor/io/products.hpp"
#include "processor/pipeline/compare_internal.hpp"
#include "processor/pipeline/compare_stage.hpp"

namespace pitmap::proc::pipeline {

namespace fs = std::filesystem;
using compare_detail::WriteText;
using nlohmann::json;

namespace {

// A folder of the series: its name, survey start and CRS, read from summary.json.
struct SeriesEntry {
    std::string dir, name, start_utc;
    int epsg = 0;
};

Expected<std::vector<std::string>> ExpandSeriesList(const std::vector<std::string>& dirs) {
    if (dirs.size() != 1 || fs::is_directory(dirs.front())) return dirs;
    std::ifstream in(dirs.front());
    if (!in) return Error{"compare: " + dirs.front() + ": cannot read the list of folders"};
    std::vector<std::string> out;
    const fs::path base = fs::path(dirs.front()).parent_path();
    for (std::string line; std::getline(in, line);) {
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
        const auto first = line.find_first_not_of(' ');
        if (first == std::string::npos || line[first] == '#') continue;
        const fs::path p(line.substr(first));
        out.push_back((p.is_absolute() ? p : base / p).string());
    }
    if (out.size() < 2)
        return Error{"compare: " + dirs.front() + ": lists " + std::to_string(out.size()) +
                     " folder(s); a series needs at least two"};
    return out;
}

Expected<SeriesEntry> ReadSeriesEntry(const std::string& dir) {
    SeriesEntry e;
    e.dir = dir;
    e.name = fs::path(dir).lexically_normal().filename().string();
    if (e.name.empty() || e.name == ".") e.name = fs::weakly_canonical(dir).filename().string();
    if (!fs::is_directory(dir)) return Error{"compare: " + dir + ": not a products folder"};
    auto s = io::ReadSummaryJson((fs::path(dir) / "summary.json").string());
    if (!s) return Error{"compare: " + dir + ": " + s.error().message};
    if (s->contains("metadata") && (*s)["metadata"].is_object())
        e.start_utc = (*s)["metadata"].value("survey_start_utc", std::string());
    if (e.start_utc.empty())
        return Error{"compare: " + dir +
                     ": summary.json names no survey_start_utc (metadata): the series' order "
                     "cannot be checked"};
    if (s->contains("utm") && (*s)["utm"].is_object()) e.epsg = (*s)["utm"].value("epsg", 0);
    if (e.epsg == 0) return Error{"compare: " + dir + ": summary.json names no utm.epsg"};
    return e;
}

}  // namespace

Expected<int> RunCompareSeries(const std::vector<std::string>& dirs_in,
                               const std::string& out_dir,
                               const CompareConfig& cfg,
                               const std::function<void(const std::string&)>& log) {
    auto dirs = ExpandSeriesList(dirs_in);
    if (!dirs) return dirs.error();
    if (dirs->size() < 2) return Error{"compare: a series needs at least two products folders"};
    std::vector<SeriesEntry> entries;
    for (const std::string& d : *dirs) {
        auto e = ReadSeriesEntry(d);
        if (!e) return e.error();
        if (!entries.empty()) {
            const SeriesEntry& prev = entries.back();
            // ISO 8601 UTC stamps of one form order as text.
            if (!(e->start_utc > prev.start_utc)) {
                return Error{"compare: " + d + " is out of time order: surveyed " + e->start_utc +
                             ", not after " + prev.dir + " (" + prev.start_utc +
                             "); give the folders earliest first"};
            }
            if (e->epsg != entries.front().epsg) {
                return Error{"compare: " + d + " is in another CRS (EPSG " +
                             std::to_string(e->epsg) + ") than " + entries.front().dir + " (EPSG " +
                             std::to_string(entries.front().epsg) + ")"};
            }
        }
        entries.push_back(std::move(*e));
    }
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec) return Error{"compare: " + out_dir + ": cannot create: " + ec.message()};
    json intervals = json::array();
    std::string csv =
        "interval,from,to,from_utc,to_utc,cut_m3,cut_u95_m3,fill_m3,fill_u95_m3,net_m3,"
        "net_u95_m3,cumulative_net_m3,cumulative_net_u95_m3,gates\n";
    double cumulative = 0, cumulative_var = 0;
    int gates = 0;
    for (std::size_t k = 0; k + 1 < entries.size(); ++k) {
        const SeriesEntry& a = entries[k];
        const SeriesEntry& b = entries[k + 1];
        char sub[32];
        std::snprintf(sub, sizeof sub, "%02zu_", k + 1);
        const std::string folder = sub + a.name + "_to_" + b.name;
        log("compare: interval " + std::to_string(k + 1) + ": " + a.dir + " -> " + b.dir);
        auto g = RunCompare(a.dir, b.dir, (fs::path(out_dir) / folder).string(), cfg, log);
        if (!g) return Error{g.error().message + " (interval " + std::to_string(k + 1) + ")"};
        gates += *g;
        auto cj = io::ReadJsonFile((fs::path(out_dir) / folder / "compare.json").string());
        if (!cj) return Error{"compare: " + cj.error().message};
        const json& c = *cj;
        const json& ch = c["change"];
        const double cut = ch["cut"]["volume_m3"], cut_u = ch["cut"]["u95_m3"];
        const double fill = ch["fill"]["volume_m3"], fill_u = ch["fill"]["u95_m3"];
        const double net = cut + fill, net_u = std::hypot(cut_u, fill_u);
        cumulative += net;
        cumulative_var += net_u * net_u;
        const double cumulative_u = std::sqrt(cumulative_var);
        intervals.push_back({{"interval", k + 1},
                             {"folder", folder},
                             {"from", {{"folder", a.dir}, {"survey_start_utc", a.start_utc}}},
                             {"to", {{"folder", b.dir}, {"survey_start_utc", b.start_utc}}},
                             {"cut_m3", cut},
                             {"cut_u95_m3", cut_u},
                             {"fill_m3", fill},
                             {"fill_u95_m3", fill_u},
                             {"net_m3", net},
                             {"net_u95_m3", net_u},
                             {"cumulative_net_m3", cumulative},
                             {"cumulative_net_u95_m3", cumulative_u},
                             {"quality_gates", c["quality_gates"]}});
        char line[512];
        std::snprintf(line,
                      sizeof line,
                      "%zu,%s,%s,%s,%s,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d\n",
                      k + 1,
                      a.name.c_str(),
                      b.name.c_str(),
                      a.start_utc.c_str(),
                      b.start_utc.c_str(),
                      cut,
                      cut_u,
                      fill,
                      fill_u,
                      net,
                      net_u,
                      cumulative,
                      cumulative_u,
                      *g);
        csv += line;
    }
    json surveys = json::array();
    for (const SeriesEntry& e : entries)
        surveys.push_back(
            {{"folder", fs::weakly_canonical(e.dir).string()}, {"survey_start_utc", e.start_utc}});
    const json series = {{"surveys", surveys},
                         {"epsg", entries.front().epsg},
                         {"intervals", intervals},
                         {"cumulative_net_m3", cumulative},
                         {"cumulative_net_u95_m3", std::sqrt(cumulative_var)},
                         {"quality_gates_tripped", gates}};
    if (auto s = WriteText((fs::path(out_dir) / "series.csv").string(), csv); !s)
        return Error{"compare: " + s.error().message};
    if (auto s = WriteText((fs::path(out_dir) / "series.json").string(), series.dump(2) + "\n"); !s)
        return Error{"compare: " + s.error().message};
    log("compare: series of " + std::to_string(entries.size()) + " surveys, " +
        std::to_string(entries.size() - 1) + " intervals in " + out_dir);
    return gates;
}

}  // namespace pitmap::proc::pipeline
