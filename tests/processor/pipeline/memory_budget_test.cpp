// SPDX-License-Identifier: MIT
// The run's memory budget (issue 38, docs/decisions/018-memory-budget.md): summary.json's
// "memory" carries the budget and block size, and a stage whose peak resident memory is over
// the budget leaves the quality gate STAGE/memory_budget, which the stage's next run clears.
#include <gtest/gtest.h>

#include <filesystem>
#include <limits>
#include <string>

#include "common/peak_memory.hpp"
#include "processor/pipeline/internal.hpp"

namespace pitmap::proc::pipeline::detail {
namespace {

std::string ViewSpillPathForTest(const StageContext& s) {
    return io::ViewSpillPath(s.out_dir);
}

std::size_t GatesOf(const nlohmann::json& summary, const std::string& stage) {
    std::size_t n = 0;
    if (!summary.contains("quality_gates")) return 0;
    for (const auto& g : summary["quality_gates"]) {
        if (g.value("stage", "") == stage && g.value("gate", "") == "memory_budget") ++n;
    }
    return n;
}

TEST(MemoryBudget, SummaryCarriesTheBudgetAndTheBlockSize) {
    RunOptions run;
    run.memory_budget_mb = 1500;
    run.block_soundings = 65536;
    nlohmann::json summary = nlohmann::json::object();
    SetMemoryBudget(summary, run);
    EXPECT_EQ(summary["memory"]["budget_mb"].get<double>(), 1500);
    EXPECT_EQ(summary["memory"]["block_soundings"].get<int>(), 65536);
}

TEST(MemoryBudget, AStageOverTheBudgetTripsItsGateAndTheNextRunClearsIt) {
    StageContext s;
    RunOptions run;
    // 1 MB: below any process's resident memory, so the stage is over it whatever it holds.
    run.memory_budget_mb = 1;
    SetMemoryBudget(s.summary, run);
    {
        StageClock clock;
        RecordStage(s.summary, Stage::kGrid, nlohmann::json::object(), clock);
    }
    ASSERT_EQ(GatesOf(s.summary, "grid"), 1u) << s.summary.dump();
    EXPECT_GT(s.summary["stages"]["grid"]["peak_rss_mb"].get<double>(), 1.0);
    const std::string message = s.summary["quality_gates"][0]["message"];
    EXPECT_NE(message.find("over run.memory_budget_mb (1 MB)"), std::string::npos) << message;
    // The stage again (ClearGates at its start) under a budget it fits in: no gate.
    ClearGates(s, Stage::kGrid);
    run.memory_budget_mb = 1e9;
    SetMemoryBudget(s.summary, run);
    {
        StageClock clock;
        RecordStage(s.summary, Stage::kGrid, nlohmann::json::object(), clock);
    }
    EXPECT_EQ(GatesOf(s.summary, "grid"), 0u) << s.summary.dump();
    // Without a budget in the summary (a survey of an older version) nothing is compared.
    nlohmann::json old = nlohmann::json::object();
    StageClock clock;
    RecordStage(old, Stage::kFuse, nlohmann::json::object(), clock);
    EXPECT_EQ(GatesOf(old, "fuse"), 0u);
}

TEST(MemoryBudget, ABlockShrinksToWhatTheBudgetLeaves) {
    RunOptions run;
    run.memory_budget_mb = 1000;
    run.block_soundings = 1 << 20;  // 64 MB a block at kBlockBytesPerSounding
    // Room for the whole block: the configured one.
    EXPECT_EQ(BlockWithinBudget(run, 100), std::size_t{1} << 20);
    EXPECT_EQ(BlockWithinBudget(run, 1000 - 64), std::size_t{1} << 20);
    // 16 MB left: a quarter of the block, in soundings of kBlockBytesPerSounding.
    EXPECT_EQ(BlockWithinBudget(run, 1000 - 16),
              static_cast<std::size_t>(16 * 1048576 / kBlockBytesPerSounding));
    EXPECT_LT(BlockWithinBudget(run, 1000 - 16), std::size_t{1} << 20);
    // At or over the budget: the smallest block, never none.
    EXPECT_EQ(BlockWithinBudget(run, 1000), kMinBlockSoundings);
    EXPECT_EQ(BlockWithinBudget(run, 5000), kMinBlockSoundings);
    // No budget: the configured block whatever the process holds.
    run.memory_budget_mb = std::numeric_limits<double>::infinity();
    EXPECT_EQ(BlockWithinBudget(run, 1e6), std::size_t{1} << 20);
}

TEST(MemoryBudget, ABudgetJustOverTheResidentMemoryLeavesSmallBlocks) {
    // What the point writers are given (WritePoints, the grid stage's points_utm.ply) in this
    // process: the configured block under a roomy budget, a small one under a tight budget (the
    // writer's file is the same for any block: ProductReaders.ProjectedPointsInBlocks...).
    RunOptions roomy;
    roomy.memory_budget_mb = 1e6;
    RunOptions tight = roomy;
    const double resident = ResidentMb();
    ASSERT_GT(resident, 1.0);
    // Just over the resident memory: 2048 soundings' worth of headroom.
    tight.memory_budget_mb = resident + 2048 * kBlockBytesPerSounding / 1048576.0;
    const std::size_t big = BlockWithinBudget(roomy, ResidentMb());
    const std::size_t small = BlockWithinBudget(tight, ResidentMb());
    EXPECT_EQ(big, static_cast<std::size_t>(roomy.block_soundings));
    EXPECT_LE(small, std::size_t{2048});
    EXPECT_GE(small, kMinBlockSoundings);
}

TEST(MemoryBudget, TheSpilledViewComesBackBitForBit) {
    StageContext s;
    s.out_dir = ::testing::TempDir();
    georef::GeorefPoints& P = s.geo.points;
    for (std::uint32_t j = 0; j < 5000; ++j) {
        P.position_world.emplace_back(0.1 * j, -3.0 / (j + 1), 1e-9 * j * j);
        P.ping.push_back(j / 7);
        P.beam.push_back(static_cast<std::uint16_t>(j % 7));
        P.range_m.push_back(0.5f + 0.001f * static_cast<float>(j));
        P.angle_rad.push_back(-1.0f + 0.0004f * static_cast<float>(j));
    }
    const georef::GeorefPoints before = P;
    ASSERT_TRUE(SpillView(s));
    EXPECT_EQ(s.geo.points.size(), 0u);
    EXPECT_EQ(s.geo.points.position_world.capacity(), 0u);  // the memory is returned
    EXPECT_TRUE(std::filesystem::exists(ViewSpillPathForTest(s)));
    // Spilling again while spilled does not lose the held points.
    ASSERT_TRUE(SpillView(s));
    ASSERT_TRUE(RestoreView(s));
    EXPECT_FALSE(std::filesystem::exists(ViewSpillPathForTest(s)));
    EXPECT_EQ(P.position_world, before.position_world);
    EXPECT_EQ(P.ping, before.ping);
    EXPECT_EQ(P.beam, before.beam);
    EXPECT_EQ(P.range_m, before.range_m);
    EXPECT_EQ(P.angle_rad, before.angle_rad);
    EXPECT_TRUE(P.status.empty());
    // Nothing spilled: restoring is nothing.
    ASSERT_TRUE(RestoreView(s));
    EXPECT_EQ(P.size(), before.size());
}

TEST(MemoryBudget, AViewThatCannotBeSpilledStaysHeldAndSaysWhere) {
    StageContext s;
    s.out_dir = ::testing::TempDir() + "/no_such_folder_for_the_view/deeper";
    s.geo.points.position_world.emplace_back(1, 2, 3);
    s.geo.points.ping.push_back(0);
    s.geo.points.beam.push_back(0);
    s.geo.points.range_m.push_back(1);
    s.geo.points.angle_rad.push_back(0);
    const Status st = SpillView(s);
    ASSERT_FALSE(st);
    EXPECT_NE(st.error().message.find("no_such_folder_for_the_view"), std::string::npos)
        << st.error().message;
    EXPECT_EQ(s.geo.points.size(), 1u);
    EXPECT_FALSE(s.spilled_view.has_value());
}

}  // namespace
}  // namespace pitmap::proc::pipeline::detail
