// SPDX-License-Identifier: MIT
// Work folders of tests under ::testing::TempDir(): made empty when a test asks for one, and
// removed when the whole test program has passed (a failed run keeps them for a look). Without
// this every run left its logs, captures and products in the temporary directory.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <mutex>
#include <system_error>
#include <vector>

namespace pitmap::test {

namespace detail {

class WorkDirCleanup : public ::testing::Environment {
public:
    static WorkDirCleanup& Get() {
        // Registered once; gtest owns it and calls TearDown after the last test.
        static WorkDirCleanup* const instance = [] {
            auto* env = new WorkDirCleanup;
            ::testing::AddGlobalTestEnvironment(env);
            return env;
        }();
        return *instance;
    }
    void Add(const std::filesystem::path& dir) {
        const std::lock_guard<std::mutex> lock(mutex_);
        dirs_.push_back(dir);
    }
    void TearDown() override {
        if (!::testing::UnitTest::GetInstance()->Passed()) return;
        const std::lock_guard<std::mutex> lock(mutex_);
        for (const auto& dir : dirs_) {
            std::error_code ec;  // a test may have removed it already
            std::filesystem::remove_all(dir, ec);
        }
        dirs_.clear();
    }

private:
    std::mutex mutex_;
    std::vector<std::filesystem::path> dirs_;
};

}  // namespace detail

// dir, emptied and created, and removed after the test program if every test passed.
inline std::filesystem::path MakeWorkDir(const std::filesystem::path& dir) {
    detail::WorkDirCleanup::Get().Add(dir);
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

}  // namespace pitmap::test
