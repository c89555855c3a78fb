// SPDX-License-Identifier: MIT
// The run's memory budget (issue 38, docs/decisions/018-memory-budget.md): summary.json's
// "memory" carries the budget and block size, and a stage whose peak resident memory is over
// the budget leaves the quality gate STAGE/memory_budget, which the stage's next run clears.
#include <gtest/gtest.h>

#include <string>

#include "processor/pipeline/internal.hpp"

namespace pitmap::proc::pipeline::detail {
namespace {

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

}  // namespace
}  // namespace pitmap::proc::pipeline::detail
