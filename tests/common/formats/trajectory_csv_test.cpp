// SPDX-License-Identifier: MIT
// The trajectory CSV module (common/formats/trajectory_csv): per-ping and INS-rate files round
// trip; truncated and corrupted files are errors naming the file and line.
#include "common/formats/trajectory_csv.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/formats/replace_file.hpp"
#include "common/frames.hpp"

namespace pitmap::formats {
namespace {

namespace fs = std::filesystem;

class TrajectoryCsvFile : public ::testing::Test {
protected:
    void SetUp() override {
        path_ = (fs::path(::testing::TempDir()) /
                 ("pitmap_trajectory_" + std::to_string(::getpid()) + ".csv"))
                    .string();
    }
    void TearDown() override { fs::remove(path_); }
    void Write(const std::string& text) { std::ofstream(path_, std::ios::trunc) << text; }
    std::string path_;
};

TrajectoryCsv Sample(bool ins) {
    TrajectoryCsv t;
    t.ins_columns = ins;
    for (int i = 0; i < 50; ++i) {
        const double a = 0.1 * i;
        TrajectoryRow r = RowOf(
            1.4e9 + 0.02 * i,
            MakePose(frames::RotationWorldFromRpy(0.01 * std::sin(a), -0.02 * a, 3.0 - 0.1 * a),
                     Eigen::Vector3d(100 * std::cos(a), -250.5 + i, -1.25)));
        if (ins) {
            r.velocity_enu_mps = Eigen::Vector3d(1.5, -0.25 * i, 0.01);
            r.ins_status = i % 3;
        }
        t.rows.push_back(r);
    }
    return t;
}

TEST_F(TrajectoryCsvFile, PerPingAndInsRateFilesRoundTrip) {
    for (const bool ins : {false, true}) {
        const TrajectoryCsv t = Sample(ins);
        ASSERT_TRUE(WriteTrajectoryCsv(path_, t).ok());
        const auto back = ReadTrajectoryCsv(path_);
        ASSERT_TRUE(back.ok()) << back.error().message;
        EXPECT_EQ(back->ins_columns, ins);
        ASSERT_EQ(back->rows.size(), t.rows.size());
        for (std::size_t i = 0; i < t.rows.size(); ++i) {
            const TrajectoryRow &a = t.rows[i], &b = back->rows[i];
            EXPECT_NEAR(b.gps_time_s, a.gps_time_s, 1e-6);
            EXPECT_LT((b.position_world_m - a.position_world_m).norm(), 2e-5);
            const Pose pa = PoseOf(a), pb = PoseOf(b);
            EXPECT_LT(Eigen::AngleAxisd(pa.linear().transpose() * pb.linear()).angle(), 1e-6);
            EXPECT_LT((pb.translation() - pa.translation()).norm(), 2e-5);
            if (ins) {
                EXPECT_LT((b.velocity_enu_mps - a.velocity_enu_mps).norm(), 1e-4);
                EXPECT_EQ(b.ins_status, a.ins_status);
            }
        }
    }
}

TEST_F(TrajectoryCsvFile, ExtraColumnsAreIgnoredAndCrLfIsAccepted) {
    Write(
        "gps_time_s,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg,quality\r\n"
        "1.0,1,2,3,0,0,90,7\r\n2.0,4,5,6,0,0,-90,8\r\n");
    const auto r = ReadTrajectoryCsv(path_);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_FALSE(r->ins_columns);
    ASSERT_EQ(r->rows.size(), 2u);
    EXPECT_EQ(r->rows[1].position_world_m, Eigen::Vector3d(4, 5, 6));
    EXPECT_EQ(r->rows[1].yaw_deg, -90.0);
}

TEST_F(TrajectoryCsvFile, TruncatedAndCorruptFilesAreErrorsNamingFileAndLine) {
    ASSERT_TRUE(WriteTrajectoryCsv(path_, Sample(true)).ok());
    std::string text;
    {
        std::ifstream in(path_);
        std::stringstream ss;
        ss << in.rdbuf();
        text = ss.str();
    }
    auto expect_error = [&](const std::string& bytes, const std::string& where) {
        Write(bytes);
        const auto r = ReadTrajectoryCsv(path_);
        ASSERT_FALSE(r.ok()) << where;
        EXPECT_NE(r.error().message.find(path_ + where), std::string::npos)
            << where << ": " << r.error().message;
    };
    // Cut inside the third row's INS columns and inside its pose columns.
    const std::size_t row3 = [&] {
        std::size_t p = 0;
        for (int k = 0; k < 3; ++k) p = text.find('\n', p) + 1;
        return p;
    }();
    const std::size_t row3_end = text.find('\n', row3);
    const std::size_t last_comma = text.rfind(',', row3_end);
    expect_error(text.substr(0, last_comma), ":4: malformed INS columns");
    expect_error(text.substr(0, row3 + 20), ":4: malformed row");
    // A header that is no trajectory's, a time going back, a non-number.
    expect_error("gps_time_s,x_m,y_m\n1,2,3\n", ": not a trajectory CSV");
    expect_error("", ": not a trajectory CSV");
    std::string back_in_time = text;
    back_in_time.replace(row3, 2, "13");  // 1.4e9 -> 1.3e9-ish
    expect_error(back_in_time, ":4:");
    std::string garbage = text;
    garbage[row3 + 3] = 'x';
    expect_error(garbage, ":4: malformed row");
    expect_error(text.substr(0, row3) + "1400000000.1,0,0,0,0,0,0,1,2,3,zero\n",
                 ":4: malformed INS columns");
    EXPECT_FALSE(ReadTrajectoryCsv(path_ + ".missing").ok());
}

std::string ReadAll(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream o;
    o << in.rdbuf();
    return o.str();
}

// The row-by-row writer (the simulator's hours-long truth) writes the same bytes as the
// whole-file writer, and only once finished.
TEST_F(TrajectoryCsvFile, RowByRowWriterWritesTheSameFileOnceFinished) {
    for (const bool ins : {false, true}) {
        const TrajectoryCsv t = Sample(ins);
        ASSERT_TRUE(WriteTrajectoryCsv(path_, t).ok());
        const std::string whole = ReadAll(path_);
        fs::remove(path_);
        auto w = TrajectoryCsvWriter::Open(path_, ins);
        ASSERT_TRUE(w.ok()) << w.error().message;
        for (const TrajectoryRow& r : t.rows) (*w)->Append(r);
        EXPECT_FALSE(fs::exists(path_));  // still the partial file
        ASSERT_TRUE((*w)->Finish().ok());
        EXPECT_EQ(ReadAll(path_), whole);
        EXPECT_FALSE((*w)->Finish().ok());  // once only
        EXPECT_FALSE(fs::exists(PartialPath(path_)));
    }
}

// Abandoned (an error or a cancel before Finish): the earlier file stays, no partial file.
TEST_F(TrajectoryCsvFile, RowByRowWriterAbandonedLeavesTheEarlierFile) {
    ASSERT_TRUE(WriteTrajectoryCsv(path_, Sample(false)).ok());
    const std::string before = ReadAll(path_);
    {
        auto w = TrajectoryCsvWriter::Open(path_);
        ASSERT_TRUE(w.ok());
        (*w)->Append(Sample(false).rows.front());
    }
    EXPECT_EQ(ReadAll(path_), before);
    EXPECT_FALSE(fs::exists(PartialPath(path_)));
    const std::string bad = "/nonexistent-dir-pitmap/trajectory.csv";
    auto w = TrajectoryCsvWriter::Open(bad);
    ASSERT_FALSE(w.ok());
    EXPECT_NE(w.error().message.find("/nonexistent-dir-pitmap/"), std::string::npos);
}

TEST(TrajectoryCsvWrite, UnwritablePathIsAnErrorNamingIt) {
    const std::string path = "/nonexistent-dir-pitmap/trajectory.csv";
    const Status s = WriteTrajectoryCsv(path, TrajectoryCsv{});
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.error().message.find(path), std::string::npos);
}

}  // namespace
}  // namespace pitmap::formats
