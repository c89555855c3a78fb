// SPDX-License-Identifier: MIT
// Issue 35: the hand edits and the cleaning's flags through the programs, on a 20 s simulated
// survey (a few seconds in all). A hand-written P/edits.json rejecting a run of soundings makes
// them status 9 (manual) in points.ply and summary.json's soundings.rejected.manual after
// `pitmap clean`; a restore after the reject brings them back; an edit log of another survey,
// or a damaged one, stops georef and clean with a message naming edits.json and nothing of it
// applied; `pitmap rerun` keeps the manual flags; `pitmap clean` twice gives the same flags.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/formats/ply.hpp"
#include "processor/survey/edit_log.hpp"
#include "processor/survey/survey_file.hpp"
#include "tests/support/scenario.hpp"

namespace {

namespace fs = std::filesystem;
namespace survey = pitmap::proc::survey;
using pitmap::test::FreshDir;
using pitmap::test::kBin;
using pitmap::test::Quote;
using pitmap::test::ReadJson;
using pitmap::test::RunCommand;

// A sounding: (ping index in the survey's ping series, beam).
using Sounding = std::pair<std::uint32_t, std::uint32_t>;

constexpr int kManual = static_cast<int>(survey::SoundingStatus::kManual);

bool Contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

std::string ReadText(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

survey::SurveyModel LoadModel(const fs::path& P) {
    auto m = survey::LoadSurvey((P / survey::kSurveyFileName).string());
    EXPECT_TRUE(m.ok()) << m.error().message;
    return m.ok() ? std::move(*m) : survey::SurveyModel{};
}

// points.ply's status per sounding. The PLY's ping is an index into the georeferenced pings:
// the soundings are matched to the survey's pings by their time (the same double the writer
// computed from the survey's ping time).
std::map<Sounding, int> PlyStatuses(const fs::path& P) {
    const survey::SurveyModel m = LoadModel(P);
    std::map<double, std::uint32_t> ping_at;
    for (std::size_t k = 0; k < m.ingest.pings.pings.size(); ++k) {
        ping_at[static_cast<double>(m.ingest.pings.pings[k].utime_gps) * 1e-6] =
            static_cast<std::uint32_t>(k);
    }
    std::map<Sounding, int> out;
    const auto ply = pitmap::formats::ply::ReadMesh((P / "points.ply").string(),
                                                    {"gps_time_s", "beam", "status"});
    EXPECT_TRUE(ply.ok()) << ply.error().message;
    if (!ply.ok()) return out;
    const auto& v = ply->vertex_properties;
    for (std::size_t i = 0; i < v[0].size(); ++i) {
        const auto it = ping_at.find(v[0][i]);
        EXPECT_NE(it, ping_at.end()) << "a sounding at no ping's time: " << v[0][i];
        if (it == ping_at.end()) continue;
        const bool fresh = out.emplace(Sounding{it->second, static_cast<std::uint32_t>(v[1][i])},
                                       static_cast<int>(v[2][i]))
                               .second;
        EXPECT_TRUE(fresh) << "sounding written twice: ping " << it->second << " beam " << v[1][i];
    }
    return out;
}

std::set<Sounding> WithStatus(const std::map<Sounding, int>& statuses, int status) {
    std::set<Sounding> out;
    for (const auto& [s, st] : statuses) {
        if (st == status) out.insert(s);
    }
    return out;
}

std::int64_t ManualInSummary(const fs::path& P) {
    return ReadJson(P / "summary.json").at("soundings").at("rejected").at("manual").get<int64_t>();
}

// An edit log of P's survey with one edit per action, each over `runs`.
void WriteEdits(const fs::path& P,
                const std::vector<survey::ManualEdit>& actions,
                const std::vector<survey::SoundingRun>& runs) {
    survey::EditLog log;
    log.survey = survey::IdentityOf(LoadModel(P).ingest.pings);
    for (const survey::ManualEdit a : actions) {
        survey::Edit e;
        e.action = a;
        e.at_utc = "2026-06-15T09:30:00Z";
        e.source = "edit_flags_scenario_test";
        e.runs = runs;
        log.edits.push_back(e);
    }
    const pitmap::Status st = survey::WriteEditLog((P / survey::kEditLogFileName).string(), log);
    ASSERT_TRUE(st.ok()) << st.error().message;
}

class EditFlags : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = new fs::path(FreshDir("pitmap_edit_flags"));
        // The survey, and a shorter one (another survey: other pings).
        for (const auto& [name, seconds] : {std::pair{"sim", 20}, std::pair{"other", 10}}) {
            std::string out;
            ASSERT_EQ(RunCommand(kBin + "/pitmap-sim synth --scenario demo --duration " +
                                     std::to_string(seconds) + " --out " + Quote(*dir_ / name),
                                 &out),
                      0)
                << out;
        }
    }
    static void TearDownTestSuite() {
        delete dir_;
        dir_ = nullptr;
    }

    // `pitmap COMMAND --out P` (georef: of the survey `sim`); its exit status.
    static int Pitmap(const std::string& command,
                      const fs::path& P,
                      std::string* out,
                      const std::string& sim = "sim") {
        const std::string inputs = command == "georef" ? Quote(*dir_ / sim / "log") + " " : "";
        return RunCommand(kBin + "/pitmap " + command + " " + inputs + "--out " + Quote(P), out);
    }
    static fs::path Georef(const std::string& name, const std::string& sim = "sim") {
        const fs::path P = *dir_ / name;
        std::string out;
        EXPECT_EQ(Pitmap("georef", P, &out, sim), 0) << out;
        return P;
    }

    // A bad edit log in georeferenced folder P: clean stops naming it and leaves the survey and
    // the points as they were; georef there stops too and leaves no survey with the log applied;
    // the log (the user's) is kept as it is.
    static void ExpectTheLogStopsCleanAndGeoref(const fs::path& P) {
        const std::string log_before = ReadText(P / survey::kEditLogFileName);
        const std::string survey_before = ReadText(P / survey::kSurveyFileName);
        const std::string points_before = ReadText(P / "points.ply");
        for (const char* command : {"clean", "georef"}) {
            SCOPED_TRACE(command);
            std::string out;
            EXPECT_NE(Pitmap(command, P, &out), 0) << out;
            EXPECT_TRUE(Contains(out, (P / survey::kEditLogFileName).string())) << out;
            if (fs::exists(P / survey::kSurveyFileName)) {
                EXPECT_EQ(ReadText(P / survey::kSurveyFileName), survey_before);
            }
            if (std::string(command) == "clean") {
                EXPECT_EQ(ReadText(P / "points.ply"), points_before);
            }
        }
        EXPECT_EQ(ReadText(P / survey::kEditLogFileName), log_before);
    }

    // A run of 20 consecutive beams of one ping in the middle of the survey that georef
    // accepted (so that a manual reject is their only rejection).
    static survey::SoundingRun AcceptedRun(const fs::path& P) {
        const std::map<Sounding, int> st = PlyStatuses(P);
        const std::uint32_t ping =
            static_cast<std::uint32_t>(LoadModel(P).ingest.pings.pings.size() / 2);
        std::uint32_t first = 0, length = 0;
        for (std::uint32_t beam = 0; beam < 1024 && length < 20; ++beam) {
            const auto it = st.find({ping, beam});
            if (it != st.end() && it->second == 0) {
                if (length == 0) first = beam;
                ++length;
            } else {
                length = 0;
            }
        }
        EXPECT_EQ(length, 20u) << "no run of 20 accepted beams in ping " << ping;
        return {ping, first, 20};
    }
    static std::set<Sounding> SoundingsOf(const survey::SoundingRun& r) {
        std::set<Sounding> out;
        for (std::uint32_t b = 0; b < r.count; ++b) out.insert({r.ping, r.first_beam + b});
        return out;
    }

    static fs::path* dir_;
};

fs::path* EditFlags::dir_ = nullptr;

TEST_F(EditFlags, AHandRejectIsManualInThePointsAndTheSummary) {
    const fs::path P = Georef("reject");
    const survey::SoundingRun run = AcceptedRun(P);
    WriteEdits(P, {survey::ManualEdit::kReject}, {run});
    std::string out;
    ASSERT_EQ(Pitmap("clean", P, &out), 0) << out;
    EXPECT_TRUE(Contains(out, "20 soundings rejected and 0 restored by hand")) << out;
    const std::map<Sounding, int> st = PlyStatuses(P);
    EXPECT_EQ(WithStatus(st, kManual), SoundingsOf(run));
    EXPECT_EQ(ManualInSummary(P), 20);
    // The cleaning decided without them: none of them carries a cleaning verdict.
    const survey::SurveyModel m = LoadModel(P);
    ASSERT_EQ(m.flags.cleaning.size(), m.ingest.pings.range_counts.size());
    const std::size_t offset = m.ingest.pings.pings[run.ping].beam_offset;
    for (std::uint32_t b = 0; b < run.count; ++b) {
        EXPECT_EQ(m.flags.cleaning[offset + run.first_beam + b], 0) << b;
    }
}

TEST_F(EditFlags, ARestoreAfterTheRejectBringsThemBack) {
    const fs::path P = Georef("restore");
    const survey::SoundingRun run = AcceptedRun(P);
    WriteEdits(P, {survey::ManualEdit::kReject}, {run});
    std::string out;
    ASSERT_EQ(Pitmap("clean", P, &out), 0) << out;
    ASSERT_EQ(ManualInSummary(P), 20);
    WriteEdits(P, {survey::ManualEdit::kReject, survey::ManualEdit::kRestore}, {run});
    out.clear();
    ASSERT_EQ(Pitmap("clean", P, &out), 0) << out;
    EXPECT_TRUE(Contains(out, "0 soundings rejected and 20 restored by hand")) << out;
    const std::map<Sounding, int> st = PlyStatuses(P);
    EXPECT_TRUE(WithStatus(st, kManual).empty());
    for (const Sounding& s : SoundingsOf(run)) {
        const auto it = st.find(s);
        ASSERT_NE(it, st.end()) << s.first << " " << s.second;
        EXPECT_EQ(it->second, 0) << s.first << " " << s.second;
    }
    EXPECT_EQ(ManualInSummary(P), 0);
}

TEST_F(EditFlags, AnEditLogOfAnotherSurveyStopsTheCommandAndNothingIsApplied) {
    // A log written for the other survey.
    const fs::path Q = Georef("other_survey", "other");
    WriteEdits(Q, {survey::ManualEdit::kReject}, {{10, 5, 10}});
    const std::string foreign = ReadText(Q / survey::kEditLogFileName);

    // Into a new folder: georef stops before it writes a survey.
    const fs::path R = *dir_ / "foreign_new";
    fs::create_directories(R);
    fs::copy_file(Q / survey::kEditLogFileName, R / survey::kEditLogFileName);
    std::string out;
    EXPECT_NE(Pitmap("georef", R, &out), 0) << out;
    EXPECT_TRUE(Contains(out, (R / survey::kEditLogFileName).string())) << out;
    EXPECT_FALSE(fs::exists(R / survey::kSurveyFileName));
    EXPECT_FALSE(fs::exists(R / "points.ply"));
    EXPECT_EQ(ReadText(R / survey::kEditLogFileName), foreign) << "the log is the user's: kept";

    // Into a georeferenced folder: clean stops and the survey and points stay as they were.
    const fs::path P = Georef("foreign_existing");
    fs::copy_file(Q / survey::kEditLogFileName, P / survey::kEditLogFileName);
    ExpectTheLogStopsCleanAndGeoref(P);
}

TEST_F(EditFlags, ADamagedEditLogStopsTheCommandAndNothingIsApplied) {
    const fs::path P = Georef("damaged");
    const survey::SoundingRun run = AcceptedRun(P);
    WriteEdits(P, {survey::ManualEdit::kReject}, {run});
    const std::string whole = ReadText(P / survey::kEditLogFileName);
    const std::string half = whole.substr(0, whole.size() / 2);
    std::ofstream(P / survey::kEditLogFileName, std::ios::binary | std::ios::trunc) << half;
    ExpectTheLogStopsCleanAndGeoref(P);
}

TEST_F(EditFlags, RerunKeepsTheManualFlags) {
    const fs::path P = Georef("rerun");
    const survey::SoundingRun run = AcceptedRun(P);
    WriteEdits(P, {survey::ManualEdit::kReject}, {run});
    std::string out;
    ASSERT_EQ(Pitmap("clean", P, &out), 0) << out;
    out.clear();
    ASSERT_EQ(Pitmap("rerun --no-report", P, &out), 0) << out;
    EXPECT_TRUE(Contains(out, "20 soundings rejected and 0 restored by hand")) << out;
    EXPECT_EQ(WithStatus(PlyStatuses(P), kManual), SoundingsOf(run));
    EXPECT_EQ(ManualInSummary(P), 20);
    const survey::SurveyModel m = LoadModel(P);
    EXPECT_EQ(m.flags.cleaning.size(), m.ingest.pings.range_counts.size());
}

TEST_F(EditFlags, CleaningTwiceGivesTheSameFlags) {
    const fs::path P = Georef("twice");
    const survey::SoundingRun run = AcceptedRun(P);
    WriteEdits(P, {survey::ManualEdit::kReject}, {run});
    std::string out;
    ASSERT_EQ(Pitmap("clean", P, &out), 0) << out;
    const std::vector<std::uint8_t> first = LoadModel(P).flags.cleaning;
    const std::map<Sounding, int> first_ply = PlyStatuses(P);
    ASSERT_FALSE(first.empty());
    std::size_t cleaned = 0;
    for (const std::uint8_t f : first) cleaned += f != 0;
    EXPECT_GT(cleaned, 0u) << "the demo survey has soundings the cleaning rejects";
    out.clear();
    ASSERT_EQ(Pitmap("clean", P, &out), 0) << out;
    EXPECT_TRUE(Contains(out, "0 flags changed")) << out;
    EXPECT_EQ(LoadModel(P).flags.cleaning, first);
    EXPECT_EQ(PlyStatuses(P), first_ply);
    EXPECT_EQ(WithStatus(first_ply, kManual), SoundingsOf(run));
}

}  // namespace
