// SPDX-License-Identifier: MIT
// The session of pitmap edit (processor/edit/edit_session.hpp) on a simulated survey (pitmap-sim
// synth demo with echo artifacts, pitmap georef): a reject by polygon changes exactly the
// accepted soundings inside it (counted here by brute force over the session's positions),
// saves P/edits.json, and a new session (the saved log applied by survey::LoadEdits) has the
// same statuses; restore, undo (the file follows), an edit log of another survey or a damaged
// one refuses to open naming it, and an edit log that cannot be written leaves the session as
// it was.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "processor/edit/edit_session.hpp"
#include "tests/support/scenario.hpp"

namespace pitmap::proc::edit {
namespace {

namespace fs = std::filesystem;
using survey::SoundingStatus;
using test::kBin;
using test::Quote;
using test::RunCommand;

class EditSessionTest : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = fs::temp_directory_path() / ("pitmap_edit_session_test_" + std::to_string(getpid()));
        fs::remove_all(dir_);
        fs::create_directories(dir_);
        std::string out;
        ASSERT_EQ(RunCommand(kBin +
                                 "/pitmap-sim synth --scenario demo --duration 20 "
                                 "--echo-artifacts typical --out " +
                                 Quote(dir_ / "sim"),
                             &out),
                  0)
            << out;
        ASSERT_EQ(RunCommand(kBin + "/pitmap georef " + Quote(dir_ / "sim" / "log") + " --out " +
                                 Quote(dir_ / "P"),
                             &out),
                  0)
            << out;
    }
    static void TearDownTestSuite() { fs::remove_all(dir_); }
    void SetUp() override { fs::remove(P() + "/edits.json"); }
    static std::string P() { return (dir_ / "P").string(); }
    static std::unique_ptr<EditSession> Open() {
        EditSessionConfig c;
        c.max_display_points = 10000;
        auto s = EditSession::Open(P(), c);
        EXPECT_TRUE(s) << (s ? "" : s.error().message);
        return s ? std::move(*s) : nullptr;
    }
    // A view from above: x, y of the session frame scaled into NDC, z ignored (w = 1).
    static SelectionQuery TopView(double half_width_m, std::vector<NdcPoint> polygon) {
        SelectionQuery q;
        q.view_projection = {
            1 / half_width_m, 0, 0, 0, 0, 1 / half_width_m, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1};
        q.polygon = std::move(polygon);
        return q;
    }
    static fs::path dir_;
};
fs::path EditSessionTest::dir_;

TEST_F(EditSessionTest, RejectIsExactlyTheAcceptedInsideAndIsSavedAndReloaded) {
    auto s = Open();
    ASSERT_TRUE(s);
    ASSERT_GT(s->size(), 50000u);
    EXPECT_TRUE(s->has_tvu());
    EXPECT_EQ(s->display_stride(), (s->size() + 9999) / 10000);
    EXPECT_EQ(s->DisplayStatus().size(), s->display_size());
    EXPECT_EQ(s->DisplayPositions().size(), 12 * s->display_size());
    const auto before = s->Statuses();
    const auto q = TopView(30, {{-0.5, -0.4}, {0.4, -0.5}, {0.1, 0.0}, {0.5, 0.5}, {-0.4, 0.3}});
    std::size_t inside = 0, accepted_inside = 0;
    for (std::size_t i = 0; i < s->size(); ++i) {
        const float* p = &s->positions()[3 * i];
        if (InsidePolygon(q.polygon, p[0] / 30.0, p[1] / 30.0)) {
            ++inside;
            if (before[i] == 0) ++accepted_inside;
        }
    }
    ASSERT_GT(accepted_inside, 1000u);
    auto r = s->Apply(EditAction::kReject, q);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->selected, inside);
    EXPECT_EQ(r->changed, accepted_inside);
    EXPECT_EQ(r->edits, 1u);
    const auto after = s->Statuses();
    for (std::size_t i = 0; i < s->size(); ++i) {
        const float* p = &s->positions()[3 * i];
        const bool in = InsidePolygon(q.polygon, p[0] / 30.0, p[1] / 30.0);
        const auto want =
            in && before[i] == 0 ? SoundingStatus::kManual : static_cast<SoundingStatus>(before[i]);
        ASSERT_EQ(static_cast<SoundingStatus>(after[i]), want) << i;
    }
    // Saved: the log holds the edit; a new session applies it (survey::LoadEdits' rule).
    auto log = survey::ReadEditLog(P() + "/edits.json");
    ASSERT_TRUE(log) << log.error().message;
    ASSERT_EQ(log->edits.size(), 1u);
    EXPECT_EQ(log->num_soundings(), accepted_inside);
    EXPECT_EQ(log->edits[0].source, "pitmap edit");
    auto again = Open();
    ASSERT_TRUE(again);
    EXPECT_EQ(again->Statuses(), after);
    EXPECT_EQ(again->num_edits(), 1u);
    // The same reject again changes nothing and logs nothing.
    auto r2 = again->Apply(EditAction::kReject, q);
    ASSERT_TRUE(r2);
    EXPECT_EQ(r2->changed, 0u);
    EXPECT_EQ(r2->edits, 1u);
}

TEST_F(EditSessionTest, RestoreAndUndo) {
    auto s = Open();
    ASSERT_TRUE(s);
    const auto before = s->Statuses();
    const auto counts = s->Counts();
    ASSERT_GT(counts[static_cast<int>(SoundingStatus::kSpike)], 0);
    // Restore everything: every rejection with a position becomes accepted.
    const auto all = TopView(1e6, BoxPolygon({-1, -1}, {1, 1}));
    auto r = s->Apply(EditAction::kRestore, all);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->selected, s->size());
    EXPECT_EQ(static_cast<std::int64_t>(r->changed),
              static_cast<std::int64_t>(s->size()) - counts[0]);
    EXPECT_EQ(static_cast<std::size_t>(s->Counts()[0]), s->size());
    // Reject a box, then undo twice: back to the start, and the file says so.
    auto r2 = s->Apply(EditAction::kReject, TopView(30, BoxPolygon({-0.2, -0.2}, {0.2, 0.2})));
    ASSERT_TRUE(r2);
    EXPECT_GT(r2->changed, 0u);
    auto u = s->Undo();
    ASSERT_TRUE(u);
    EXPECT_EQ(u->changed, r2->changed);
    EXPECT_EQ(static_cast<std::size_t>(s->Counts()[0]), s->size());
    ASSERT_TRUE(s->Undo());
    EXPECT_EQ(s->Statuses(), before);
    EXPECT_FALSE(s->Undo());
    auto log = survey::ReadEditLog(P() + "/edits.json");
    ASSERT_TRUE(log);
    EXPECT_TRUE(log->edits.empty());
}

TEST_F(EditSessionTest, ForeignOrDamagedLogRefusesToOpen) {
    const std::string path = P() + "/edits.json";
    std::ofstream(path) << "{\"pitmap_edit_log\": 1, \"survey\": {\"pings\": 3, ";
    EditSessionConfig c;
    auto s = EditSession::Open(P(), c);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find(path), std::string::npos) << s.error().message;
    survey::EditLog other;
    other.survey = {200, 96000, "0123456789abcdef"};
    ASSERT_TRUE(survey::WriteEditLog(path, other));
    s = EditSession::Open(P(), c);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find(path), std::string::npos);
    EXPECT_NE(s.error().message.find("another survey"), std::string::npos);
}

TEST_F(EditSessionTest, UnwritableLogLeavesTheSessionAsItWas) {
    auto s = Open();
    ASSERT_TRUE(s);
    const auto before = s->Statuses();
    fs::create_directory(P() + "/edits.json");  // a folder where the file goes
    auto r = s->Apply(EditAction::kReject, TopView(30, BoxPolygon({-0.2, -0.2}, {0.2, 0.2})));
    fs::remove_all(P() + "/edits.json");
    ASSERT_FALSE(r);
    EXPECT_NE(r.error().message.find("edits.json"), std::string::npos) << r.error().message;
    EXPECT_EQ(s->Statuses(), before);
    EXPECT_EQ(s->num_edits(), 0u);
}

}  // namespace
}  // namespace pitmap::proc::edit
