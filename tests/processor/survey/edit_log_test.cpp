// SPDX-License-Identifier: MIT
// The edit log (processor/survey/edit_log.hpp): a round trip keeps every edit; a log of another
// survey, a damaged file and a run outside the survey are errors naming the file, and nothing of
// them is applied; edits apply in order (a later one wins); RunsOf merges consecutive beams of
// a ping and drops repeats and indices outside the pings.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "processor/survey/edit_log.hpp"

namespace pitmap::proc::survey {
namespace {

namespace fs = std::filesystem;
using survey::ManualEdit;

// Pings of `beams` beams each, numbered from 100.
survey::PingSeries MakePings(const std::vector<std::uint16_t>& beams) {
    survey::PingSeries s;
    std::uint32_t offset = 0;
    for (std::size_t i = 0; i < beams.size(); ++i) {
        survey::PingHeader h;
        h.utime_gps = 1'000'000 * static_cast<std::int64_t>(i + 1);
        h.ping_number = 100 + static_cast<std::int64_t>(i);
        h.beam_offset = offset;
        h.num_beams = beams[i];
        offset += beams[i];
        s.pings.push_back(h);
    }
    s.range_counts.assign(offset, 1000);
    return s;
}

class EditLogTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("pitmap_edit_log_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    std::string Path() const { return (dir_ / kEditLogFileName).string(); }
    void WriteText(const std::string& text) const { std::ofstream(Path()) << text; }
    fs::path dir_;
};

TEST_F(EditLogTest, RoundTripKeepsEveryEdit) {
    const auto pings = MakePings({10, 10, 12});
    EditLog log;
    log.survey = IdentityOf(pings);
    log.edits.push_back({ManualEdit::kReject, "2024-05-01T10:00:00Z", "pitmap edit", {{0, 2, 3}}});
    log.edits.push_back(
        {ManualEdit::kRestore, "2024-05-01T10:01:00Z", "a script", {{1, 0, 10}, {2, 11, 1}}});
    ASSERT_TRUE(WriteEditLog(Path(), log));
    auto back = ReadEditLog(Path());
    ASSERT_TRUE(back) << back.error().message;
    EXPECT_EQ(back->survey, log.survey);
    ASSERT_EQ(back->edits.size(), 2u);
    for (std::size_t i = 0; i < 2; ++i) {
        EXPECT_EQ(back->edits[i].action, log.edits[i].action);
        EXPECT_EQ(back->edits[i].at_utc, log.edits[i].at_utc);
        EXPECT_EQ(back->edits[i].source, log.edits[i].source);
        ASSERT_EQ(back->edits[i].runs.size(), log.edits[i].runs.size());
        for (std::size_t r = 0; r < log.edits[i].runs.size(); ++r) {
            EXPECT_EQ(back->edits[i].runs[r].ping, log.edits[i].runs[r].ping);
            EXPECT_EQ(back->edits[i].runs[r].first_beam, log.edits[i].runs[r].first_beam);
            EXPECT_EQ(back->edits[i].runs[r].count, log.edits[i].runs[r].count);
        }
    }
    EXPECT_EQ(back->num_soundings(), 3u + 10u + 1u);
    auto manual = LoadEdits(dir_.string(), pings);
    ASSERT_TRUE(manual) << manual.error().message;
    ASSERT_EQ(manual->size(), pings.num_soundings());
    for (std::size_t j = 0; j < manual->size(); ++j) {
        const bool rejected = j >= 2 && j < 5;
        const bool restored = (j >= 10 && j < 20) || j == 20 + 11;
        const auto want = rejected   ? ManualEdit::kReject
                          : restored ? ManualEdit::kRestore
                                     : ManualEdit::kNone;
        EXPECT_EQ((*manual)[j], static_cast<std::uint8_t>(want)) << j;
    }
}

TEST_F(EditLogTest, NoFileIsNoEdits) {
    auto manual = LoadEdits(dir_.string(), MakePings({4}));
    ASSERT_TRUE(manual);
    EXPECT_TRUE(manual->empty());
}

TEST_F(EditLogTest, AnotherSurveyIsAnErrorNamingTheFile) {
    EditLog log;
    log.survey = IdentityOf(MakePings({10, 10}));
    log.edits.push_back({ManualEdit::kReject, "", "", {{0, 0, 1}}});
    ASSERT_TRUE(WriteEditLog(Path(), log));
    // Same sizes, another ping number: another fingerprint.
    auto other = MakePings({10, 10});
    other.pings[1].ping_number = 7;
    const auto r = LoadEdits(dir_.string(), other);
    ASSERT_FALSE(r);
    EXPECT_NE(r.error().message.find(Path()), std::string::npos) << r.error().message;
    EXPECT_NE(r.error().message.find("another survey"), std::string::npos);
    // More beams: another count too.
    const auto r2 = LoadEdits(dir_.string(), MakePings({10, 11}));
    ASSERT_FALSE(r2);
    EXPECT_NE(r2.error().message.find(Path()), std::string::npos);
}

TEST_F(EditLogTest, DamagedFilesAreErrorsNamingTheFile) {
    const auto pings = MakePings({10});
    const std::string id = IdentityOf(pings).fingerprint;
    const std::string survey =
        R"("survey": {"pings": 1, "soundings": 10, "fingerprint": ")" + id + R"("})";
    const std::vector<std::string> bad = {
        "",
        "{",
        R"({"pitmap_edit_log": 1, )" + survey +
            R"(, "edits": [{"action": "reject", "runs": [[0, 1)",
        "[]",
        R"({"edits": []})",
        R"({"pitmap_edit_log": 2, )" + survey + R"(, "edits": []})",
        R"({"pitmap_edit_log": "1", )" + survey + R"(, "edits": []})",
        R"({"pitmap_edit_log": 1, "edits": []})",
        R"({"pitmap_edit_log": 1, "survey": {"pings": -1, "soundings": 10, "fingerprint": "x"},
            "edits": []})",
        R"({"pitmap_edit_log": 1, )" + survey + R"(})",
        R"({"pitmap_edit_log": 1, )" + survey + R"(, "edits": [3]})",
        R"({"pitmap_edit_log": 1, )" + survey + R"(, "edits": [{"action": "delete", "runs": []}]})",
        R"({"pitmap_edit_log": 1, )" + survey + R"(, "edits": [{"action": "reject"}]})",
        // A key of another type (found by the fuzzer: json::value threw out of the reader).
        R"({"pitmap_edit_log": 1, )" + survey + R"(, "edits": [{"action": 11, "runs": []}]})",
        R"({"pitmap_edit_log": 1, )" + survey +
            R"(, "edits": [{"action": "reject", "runs": [[0, 1]]}]})",
        R"({"pitmap_edit_log": 1, )" + survey +
            R"(, "edits": [{"action": "reject", "runs": [[0, -1, 2]]}]})",
        R"({"pitmap_edit_log": 1, )" + survey +
            R"(, "edits": [{"action": "reject", "runs": [[0, 1, 4294967296]]}]})",
        R"({"pitmap_edit_log": 1, )" + survey +
            R"(, "edits": [{"action": "reject", "runs": [[0, 1.5, 2]]}]})",
    };
    for (const std::string& text : bad) {
        WriteText(text);
        const auto r = LoadEdits(dir_.string(), pings);
        ASSERT_FALSE(r) << text;
        EXPECT_NE(r.error().message.find(Path()), std::string::npos) << r.error().message;
    }
    // The same file, well formed, is read.
    WriteText(R"({"pitmap_edit_log": 1, )" + survey +
              R"(, "edits": [{"action": "reject", "runs": [[0, 1, 2]]}]})");
    const auto good = LoadEdits(dir_.string(), pings);
    ASSERT_TRUE(good) << good.error().message;
    EXPECT_EQ((*good)[2], static_cast<std::uint8_t>(ManualEdit::kReject));
}

TEST_F(EditLogTest, RunOutsideTheSurveyIsAnErrorAndNothingIsApplied) {
    const auto pings = MakePings({10, 6});
    for (const SoundingRun run : {SoundingRun{2, 0, 1},     // no ping 2
                                  SoundingRun{1, 5, 2},     // past ping 1's 6 beams
                                  SoundingRun{1, 6, 1},     // beam 6 of 6
                                  SoundingRun{0, 0, 0}}) {  // empty
        EditLog log;
        log.survey = IdentityOf(pings);
        log.edits.push_back({ManualEdit::kReject, "", "", {{0, 0, 3}}});
        log.edits.push_back({ManualEdit::kReject, "", "", {run}});
        ASSERT_TRUE(WriteEditLog(Path(), log));
        const auto r = LoadEdits(dir_.string(), pings);
        ASSERT_FALSE(r) << run.ping << " " << run.first_beam << " " << run.count;
        EXPECT_NE(r.error().message.find(Path()), std::string::npos);
        EXPECT_NE(r.error().message.find("edit 2"), std::string::npos) << r.error().message;
        EXPECT_NE(r.error().message.find("outside the survey"), std::string::npos);
    }
    // The last beam of the last ping is inside.
    EditLog log;
    log.survey = IdentityOf(pings);
    log.edits.push_back({ManualEdit::kReject, "", "", {{1, 5, 1}}});
    ASSERT_TRUE(WriteEditLog(Path(), log));
    const auto r = LoadEdits(dir_.string(), pings);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->back(), static_cast<std::uint8_t>(ManualEdit::kReject));
}

TEST_F(EditLogTest, LaterEditsWin) {
    const auto pings = MakePings({20});
    EditLog log;
    log.survey = IdentityOf(pings);
    log.edits.push_back({ManualEdit::kReject, "", "", {{0, 0, 10}}});
    log.edits.push_back({ManualEdit::kRestore, "", "", {{0, 5, 10}}});
    log.edits.push_back({ManualEdit::kReject, "", "", {{0, 12, 1}}});
    auto m = ApplyEditLog(log, pings, "edits.json");
    ASSERT_TRUE(m);
    for (std::size_t j = 0; j < 20; ++j) {
        const auto want = j == 12  ? ManualEdit::kReject
                          : j < 5  ? ManualEdit::kReject
                          : j < 15 ? ManualEdit::kRestore
                                   : ManualEdit::kNone;
        EXPECT_EQ((*m)[j], static_cast<std::uint8_t>(want)) << j;
    }
    // Undo = the last edit removed.
    log.edits.pop_back();
    m = ApplyEditLog(log, pings, "edits.json");
    ASSERT_TRUE(m);
    EXPECT_EQ((*m)[12], static_cast<std::uint8_t>(ManualEdit::kRestore));
}

TEST(RunsOf, MergesConsecutiveBeamsOfAPing) {
    const auto pings = MakePings({4, 0, 5, 3});  // flat indices: 0-3, 4-8, 9-11
    // Any order, repeats, an index past the end.
    const auto runs = RunsOf(pings, {8, 1, 2, 3, 4, 2, 5, 7, 9, 11, 12, 100});
    ASSERT_EQ(runs.size(), 5u);
    const std::vector<std::array<std::uint32_t, 3>> want = {
        {0, 1, 3}, {2, 0, 2}, {2, 3, 2}, {3, 0, 1}, {3, 2, 1}};
    for (std::size_t i = 0; i < runs.size(); ++i) {
        EXPECT_EQ(runs[i].ping, want[i][0]) << i;
        EXPECT_EQ(runs[i].first_beam, want[i][1]) << i;
        EXPECT_EQ(runs[i].count, want[i][2]) << i;
    }
    // A run never crosses from one ping into the next (beam 3 of ping 0, beam 0 of ping 2).
    const auto across = RunsOf(pings, {3, 4});
    ASSERT_EQ(across.size(), 2u);
    EXPECT_TRUE(RunsOf(pings, {}).empty());
    // The runs give back the indices.
    EditLog log;
    log.survey = IdentityOf(pings);
    log.edits.push_back({ManualEdit::kReject, "", "", runs});
    auto m = ApplyEditLog(log, pings, "x");
    ASSERT_TRUE(m);
    std::vector<std::uint32_t> back;
    for (std::uint32_t j = 0; j < m->size(); ++j) {
        if ((*m)[j] != 0) back.push_back(j);
    }
    EXPECT_EQ(back, (std::vector<std::uint32_t>{1, 2, 3, 4, 5, 7, 8, 9, 11}));
}

}  // namespace
}  // namespace pitmap::proc::survey
