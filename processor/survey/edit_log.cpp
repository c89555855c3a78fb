// SPDX-License-Identifier: MIT
#include "processor/survey/edit_log.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "common/formats/byte_file.hpp"

namespace pitmap::proc::survey {

namespace fs = std::filesystem;
using json = nlohmann::json;
using survey::ManualEdit;

namespace {

std::string Hex64(std::uint64_t v) {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
    return buf;
}

const char* ActionName(ManualEdit a) {
    return a == ManualEdit::kRestore ? "restore" : "reject";
}

}  // namespace

SurveyIdentity IdentityOf(const survey::PingSeries& pings) {
    std::uint64_t h = 1469598103934665603ull;  // FNV-1a offset basis
    auto mix = [&](std::uint64_t v) {
        for (int b = 0; b < 8; ++b) {
            h ^= (v >> (8 * b)) & 0xffu;
            h *= 1099511628211ull;
        }
    };
    for (const survey::PingHeader& p : pings.pings) {
        mix(static_cast<std::uint64_t>(p.ping_number));
        mix(p.num_beams);
    }
    return {pings.pings.size(), pings.range_counts.size(), Hex64(h)};
}

std::size_t EditLog::num_soundings() const {
    std::size_t n = 0;
    for (const Edit& e : edits) {
        for (const SoundingRun& r : e.runs) n += r.count;
    }
    return n;
}

std::vector<SoundingRun> RunsOf(const survey::PingSeries& pings, std::vector<std::uint32_t> index) {
    std::sort(index.begin(), index.end());
    index.erase(std::unique(index.begin(), index.end()), index.end());
    std::vector<SoundingRun> runs;
    std::size_t k = 0;  // the ping holding the current index (pings in beam_offset order)
    for (const std::uint32_t j : index) {
        while (k < pings.pings.size() &&
               std::size_t{pings.pings[k].beam_offset} + pings.pings[k].num_beams <= j) {
            ++k;
        }
        if (k == pings.pings.size() || j < pings.pings[k].beam_offset) continue;
        const std::uint32_t beam = j - pings.pings[k].beam_offset;
        if (!runs.empty() && runs.back().ping == k &&
            runs.back().first_beam + runs.back().count == beam) {
            ++runs.back().count;
        } else {
            runs.push_back({static_cast<std::uint32_t>(k), beam, 1});
        }
    }
    return runs;
}

Expected<EditLog> ReadEditLog(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    if (!f) return Error{path + ": cannot open the edit log"};
    std::stringstream text;
    text << f.rdbuf();
    const json j = json::parse(text.str(), nullptr, false);
    auto bad = [&](const std::string& what) {
        return Error{path + ": not a usable edit log: " + what + "; nothing of it was applied"};
    };
    if (j.is_discarded()) return bad("not JSON (damaged or cut short?)");
    if (!j.is_object() || !j.contains("pitmap_edit_log")) return bad("no \"pitmap_edit_log\" key");
    if (!j["pitmap_edit_log"].is_number_integer() || j["pitmap_edit_log"] != kEditLogVersion)
        return bad("format " + j["pitmap_edit_log"].dump() + ", this build reads " +
                   std::to_string(kEditLogVersion));
    EditLog log;
    const json& s = j.value("survey", json());
    if (!s.is_object() || !s.contains("pings") || !s["pings"].is_number_unsigned() ||
        !s.contains("soundings") || !s["soundings"].is_number_unsigned() ||
        !s.contains("fingerprint") || !s["fingerprint"].is_string())
        return bad("\"survey\" needs pings, soundings and fingerprint");
    log.survey = {s["pings"].get<std::uint64_t>(),
                  s["soundings"].get<std::uint64_t>(),
                  s["fingerprint"].get<std::string>()};
    const json& edits = j.value("edits", json());
    if (!edits.is_array()) return bad("\"edits\" is not a list");
    for (std::size_t i = 0; i < edits.size(); ++i) {
        const json& e = edits[i];
        const std::string at = "edit " + std::to_string(i + 1);
        if (!e.is_object()) return bad(at + " is not an object");
        Edit edit;
        // A key of another type is this log's damage, never an exception (json::value throws).
        const std::string action =
            e.contains("action") && e["action"].is_string() ? e["action"].get<std::string>() : "";
        if (action == "reject") {
            edit.action = ManualEdit::kReject;
        } else if (action == "restore") {
            edit.action = ManualEdit::kRestore;
        } else {
            return bad(at + ": action " + (e.contains("action") ? e["action"].dump() : "missing") +
                       " (\"reject\" or \"restore\")");
        }
        if (e.contains("at") && e["at"].is_string()) edit.at_utc = e["at"].get<std::string>();
        if (e.contains("source") && e["source"].is_string())
            edit.source = e["source"].get<std::string>();
        const json& runs = e.value("runs", json());
        if (!runs.is_array()) return bad(at + ": \"runs\" is not a list");
        edit.runs.reserve(runs.size());
        for (const json& r : runs) {
            if (!r.is_array() || r.size() != 3 || !r[0].is_number_unsigned() ||
                !r[1].is_number_unsigned() || !r[2].is_number_unsigned() ||
                r[0].get<std::uint64_t>() > UINT32_MAX || r[1].get<std::uint64_t>() > UINT32_MAX ||
                r[2].get<std::uint64_t>() > UINT32_MAX)
                return bad(at + ": a run is not [ping, first_beam, count]: " + r.dump());
            edit.runs.push_back(
                {r[0].get<std::uint32_t>(), r[1].get<std::uint32_t>(), r[2].get<std::uint32_t>()});
        }
        log.edits.push_back(std::move(edit));
    }
    return log;
}

Status WriteEditLog(const std::string& path, const EditLog& log) {
    json edits = json::array();
    for (const Edit& e : log.edits) {
        json runs = json::array();
        for (const SoundingRun& r : e.runs) runs.push_back({r.ping, r.first_beam, r.count});
        edits.push_back({{"action", ActionName(e.action)},
                         {"at", e.at_utc},
                         {"source", e.source},
                         {"runs", std::move(runs)}});
    }
    const json j = {{"pitmap_edit_log", kEditLogVersion},
                    {"survey",
                     {{"pings", log.survey.pings},
                      {"soundings", log.survey.soundings},
                      {"fingerprint", log.survey.fingerprint}}},
                    {"edits", std::move(edits)}};
    // As io::WriteJsonFile writes every JSON document (two-space indent, a final newline).
    const std::string text = j.dump(2) + "\n";
    return formats::WriteFileBytes(path, std::vector<std::uint8_t>(text.begin(), text.end()));
}

Expected<std::vector<std::uint8_t>> ApplyEditLog(const EditLog& log,
                                                 const survey::PingSeries& pings,
                                                 const std::string& path) {
    const SurveyIdentity here = IdentityOf(pings);
    if (!(log.survey == here)) {
        return Error{path + ": the edit log is of another survey (" +
                     std::to_string(log.survey.pings) + " pings, " +
                     std::to_string(log.survey.soundings) + " soundings, fingerprint " +
                     log.survey.fingerprint + "; this survey: " + std::to_string(here.pings) +
                     " pings, " + std::to_string(here.soundings) + " soundings, fingerprint " +
                     here.fingerprint + "); nothing of it was applied"};
    }
    std::vector<std::uint8_t> manual(pings.range_counts.size(), 0);
    for (std::size_t i = 0; i < log.edits.size(); ++i) {
        for (const SoundingRun& r : log.edits[i].runs) {
            if (r.ping >= pings.pings.size() || r.count == 0 ||
                std::uint64_t{r.first_beam} + r.count > pings.pings[r.ping].num_beams) {
                return Error{path + ": edit " + std::to_string(i + 1) + ": run [" +
                             std::to_string(r.ping) + ", " + std::to_string(r.first_beam) + ", " +
                             std::to_string(r.count) + "] is outside the survey; nothing of the " +
                             "edit log was applied"};
            }
            const std::size_t first = pings.pings[r.ping].beam_offset + std::size_t{r.first_beam};
            std::fill_n(manual.begin() + static_cast<std::ptrdiff_t>(first),
                        r.count,
                        static_cast<std::uint8_t>(log.edits[i].action));
        }
    }
    return manual;
}

Expected<std::vector<std::uint8_t>> LoadEdits(const std::string& out_dir,
                                              const survey::PingSeries& pings) {
    const std::string path = out_dir + "/" + kEditLogFileName;
    std::error_code ec;
    if (!fs::exists(path, ec)) return std::vector<std::uint8_t>{};
    auto log = ReadEditLog(path);
    if (!log) return log.error();
    return ApplyEditLog(*log, pings, path);
}

}  // namespace pitmap::proc::survey
