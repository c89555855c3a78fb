// SPDX-License-Identifier: MIT
// Regression on the real NovAtel captures in tests/data/novatel:
//   1. pitmap-inspect's JSON for every capture equals its golden file (golden/<capture>.json,
//      written only by tools/inspect/regen-golden.sh);
//   2. the counts tests/data/novatel/PROVENANCE.md states, checked independently of the golden
//      files (they were established with other tools before this code existed);
//   3. the pitmap-inspect program itself: same JSON, clear errors, non-zero exit codes.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tools/inspect/inspect.hpp"

namespace pitmap::tools::inspect {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kDataDir = fs::path(PITMAP_TEST_DATA_DIR) / "novatel";
const fs::path kGoldenDir = kDataDir / "golden";

std::vector<std::string> Captures() {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(kDataDir)) {
        if (!entry.is_regular_file() || entry.path().extension() == ".md") continue;
        names.push_back(entry.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
}

// As tools/inspect/regen-golden.sh runs it: --json --dump-first 2.
json Inspect(const std::string& name) {
    InspectOptions options;
    options.dump_first = 2;
    const auto report = InspectFile((kDataDir / name).string(), options);
    EXPECT_TRUE(report.ok()) << (report.ok() ? "" : report.error().message);
    return report.ok() ? ToJson(*report) : json();
}

json ReadJson(const fs::path& path) {
    std::ifstream in(path);
    if (!in) return json();
    return json::parse(in, nullptr, /*allow_exceptions=*/false);
}

TEST(GoldenFilesTest, SixteenCapturesEachWithAGoldenFileAndNoStaleOnes) {
    const auto captures = Captures();
    EXPECT_EQ(captures.size(), 16u);
    std::vector<std::string> goldens;
    for (const auto& entry : fs::directory_iterator(kGoldenDir)) {
        goldens.push_back(entry.path().filename().string());
    }
    std::sort(goldens.begin(), goldens.end());
    std::vector<std::string> expected;
    for (const auto& c : captures) expected.push_back(c + ".json");
    EXPECT_EQ(goldens, expected) << "run tools/inspect/regen-golden.sh and review the diff";
}

class GoldenTest : public ::testing::TestWithParam<std::string> {};

TEST_P(GoldenTest, InspectJsonEqualsGolden) {
    const std::string& name = GetParam();
    const json golden = ReadJson(kGoldenDir / (name + ".json"));
    ASSERT_TRUE(golden.is_object()) << "missing or unreadable golden file for " << name;
    const json actual = Inspect(name);
    EXPECT_EQ(actual, golden) << name << ": differences (RFC 6902 patch golden -> actual):\n"
                              << json::diff(golden, actual).dump(2)
                              << "\nIf the change is intended, run tools/inspect/regen-golden.sh";
}

std::string TestName(const ::testing::TestParamInfo<std::string>& param_info) {
    std::string name = param_info.param;
    for (char& ch : name) {
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
    }
    return name;
}

INSTANTIATE_TEST_SUITE_P(Novatel, GoldenTest, ::testing::ValuesIn(Captures()), TestName);

// ---- Counts from PROVENANCE.md ------------------------------------------------------------

std::uint64_t Count(const json& j, const std::string& key) {
    const auto& by_id = j.at("frames_by_id");
    return by_id.contains(key) ? by_id.at(key).get<std::uint64_t>() : 0;
}

// Every frame of the capture, by id, exactly: nothing more may appear.
void ExpectExactly(const json& j, const std::map<std::string, std::uint64_t>& expected) {
    std::map<std::string, std::uint64_t> actual;
    for (const auto& [key, value] : j.at("frames_by_id").items()) {
        actual[key] = value.get<std::uint64_t>();
    }
    EXPECT_EQ(actual, expected);
}

TEST(ProvenanceTest, CrcFailuresOnlyInGavlabTest2) {
    for (const auto& name : Captures()) {
        const json j = Inspect(name);
        const std::uint64_t expected = name == "gavlab_test2_rcvr1.dat" ? 1 : 0;
        EXPECT_EQ(j.at("crc_failures").get<std::uint64_t>(), expected) << name;
        EXPECT_EQ(j.at("skipped_bytes").at("bad_length").get<std::uint64_t>(), 0u) << name;
    }
}

TEST(ProvenanceTest, SwriBestposIs99FramesNot109) {
    const json j = Inspect("swri_bestpos-bestvel-psrdop2-sync.pcap");
    EXPECT_EQ(j.at("log_frames"), 99);
    ExpectExactly(j, {{"42", 33}, {"99", 33}, {"1163", 33}, {"PROMPT", 1}});
    EXPECT_EQ(j.at("capture").at("tcp").at(1).at("retransmitted_segments"), 10);
    EXPECT_EQ(j.at("skipped_bytes").at("total"), 0);
}

TEST(ProvenanceTest, SwriCorrimudata89FramesAnd14ResponsesAndPrompts) {
    const json j = Inspect("swri_corrimudata.pcapng");
    EXPECT_EQ(j.at("log_frames"), 89);
    ExpectExactly(j,
                  {{"42", 28},
                   {"812", 29},
                   {"1465", 28},
                   {"264", 2},
                   {"101", 2},
                   {"OK", 14},
                   {"PROMPT", 14}});
}

TEST(ProvenanceTest, Propak6BasicFix10139Frames) {
    const json j = Inspect("spandrv_propak6-basic-fix.pcap.gz");
    EXPECT_EQ(j.at("frames_total"), 10139);
    EXPECT_EQ(j.at("log_frames"), 10139);
    ExpectExactly(j, {{"42", 2187}, {"241", 1988}, {"264", 1988}, {"812", 1988}, {"1465", 1988}});
    EXPECT_EQ(j.at("skipped_bytes").at("total"), 0);
    EXPECT_EQ(j.at("truncated_tail_bytes"), 0);
}

TEST(ProvenanceTest, Propak6InsPpp7096FramesAnd1145OkPromptPairs) {
    const json j = Inspect("spandrv_propak6-ins-ppp.pcap.gz");
    EXPECT_EQ(j.at("log_frames"), 7096);
    ExpectExactly(j,
                  {{"42", 2288},
                   {"812", 2289},
                   {"1465", 2289},
                   {"264", 115},
                   {"101", 115},
                   {"OK", 1145},
                   {"PROMPT", 1145}});
    // The only skipped bytes are the CR LF before each <OK.
    EXPECT_EQ(j.at("skipped_bytes").at("total"), 2 * 1145);
}

TEST(ProvenanceTest, Oem7DriverCaptures) {
    ExpectExactly(Inspect("oem7drv_align.gps"), {{"1335", 12}});
    ExpectExactly(Inspect("oem7drv_bestpos.gps"),
                  {{"42", 5},
                   {"99", 5},
                   {"726", 2},
                   {"1163", 2},
                   {"1465", 2},
                   {"508", 10},
                   {"OK", 8},
                   {"PROMPT", 8}});
    ExpectExactly(Inspect("oem7drv_ins1.gps"),
                  {{"508", 243}, {"2264", 10}, {"2051", 29}, {"1945", 2}});
    ExpectExactly(Inspect("oem7drv_ins2.gps"),
                  {{"1362", 766}, {"508", 62}, {"1465", 6}, {"1945", 1}});
    ExpectExactly(
        Inspect("oem7drv_ins2_humble.gps"),
        {{"1362", 7}, {"508", 4}, {"1465", 4}, {"1945", 3}, {"#RXSTATUSEVENTA", 3}, {"PROMPT", 1}});
    ExpectExactly(Inspect("oem7drv_rxstatus.gps"), {{"93", 3}});
    const json time = Inspect("oem7drv_time.gps");
    ExpectExactly(time, {{"101", 6}});
    EXPECT_EQ(time.at("time_span").at("gps_start").at("week"), 2070);
    // Decoded TIME: UTC offset -18 s on 2019-09-10.
    const json& first_time = time.at("samples").at("TIME").at("first").at(0);
    EXPECT_EQ(first_time.at("utc_offset_s"), -18.0);
    EXPECT_EQ(first_time.at("utc_year"), 2019);
    EXPECT_EQ(first_time.at("utc_month"), 9);
    EXPECT_EQ(first_time.at("utc_day"), 10);
}

TEST(ProvenanceTest, DecodersAcceptEveryFrameTheyClaim) {
    for (const auto& name : Captures()) {
        const json j = Inspect(name);
        EXPECT_TRUE(j.at("decode_errors").empty()) << name << ": " << j.at("decode_errors");
        EXPECT_EQ(j.at("decoded").get<std::uint64_t>() + j.at("unsupported").get<std::uint64_t>(),
                  j.at("frames_total").get<std::uint64_t>())
            << name;
    }
    // ProPak6 INS PPP: UTC offset -16 s in November 2014; every BESTPOS/INSPVAX decoded.
    const json ppp = Inspect("spandrv_propak6-ins-ppp.pcap.gz");
    const json& time = ppp.at("samples").at("TIME");
    EXPECT_EQ(time.at("count"), 115);
    EXPECT_EQ(time.at("first").at(0).at("utc_offset_s"), -16.0);
    EXPECT_EQ(time.at("first").at(0).at("utc_year"), 2014);
    EXPECT_EQ(time.at("first").at(0).at("utc_month"), 11);
    EXPECT_EQ(ppp.at("samples").at("BESTPOS").at("count"), 2288);
    EXPECT_EQ(ppp.at("samples").at("INSPVAX").at("count"), 2289);
}

TEST(ProvenanceTest, GavlabOneEach) {
    const json j = Inspect("gavlab_OneEach.GPS");
    for (const char* id : {"42", "93", "99", "195", "241", "243", "686", "726"}) {
        EXPECT_EQ(Count(j, id), 1u) << id;
    }
    EXPECT_EQ(Count(j, "#SENDR"), 7u);
    EXPECT_EQ(Count(j, "ERROR"), 2u);
    EXPECT_GE(Count(j, "OK"), 1u);
    // The ASCII twin: the same eight logs, as ASCII.
    const json ascii = Inspect("gavlab_OneEach.ASC");
    for (const char* name : {"#BESTPOSA",
                             "#RXSTATUSA",
                             "#BESTVELA",
                             "#RXHWLEVELSA",
                             "#BESTXYZA",
                             "#PSRXYZA",
                             "#BSLNXYZA",
                             "#BESTUTMA"}) {
        EXPECT_EQ(Count(ascii, name), 1u) << name;
    }
}

TEST(ProvenanceTest, GavlabParsingData288BinaryFramesWith23Responses) {
    const json j = Inspect("gavlab_ParsingData.GPS");
    EXPECT_EQ(j.at("frames_by_kind").at("long_binary"), 288);
    EXPECT_EQ(Count(j, "1R") + Count(j, "36R"), 23u);
    EXPECT_EQ(Count(j, "42"), 84u);
    EXPECT_EQ(Count(j, "48"), 83u);
    EXPECT_EQ(Count(j, "83"), 83u);
}

TEST(ProvenanceTest, GavlabTest2Has897FramesAndOneCrcFailure) {
    const json j = Inspect("gavlab_test2_rcvr1.dat");
    EXPECT_EQ(j.at("log_frames"), 897);
    EXPECT_EQ(Count(j, "140") + Count(j, "241") + Count(j, "7"), 897u);
    EXPECT_EQ(j.at("crc_failures"), 1);
    EXPECT_EQ(j.at("skipped_bytes").at("bad_crc"), 1);  // only the false frame's sync byte
}

TEST(ProvenanceTest, RtklibOemv317FramesCutInsideAHeader) {
    const json j = Inspect("rtklib_oemv_200911218.gps");
    EXPECT_EQ(Count(j, "41") + Count(j, "42") + Count(j, "48") + Count(j, "83") + Count(j, "140") +
                  Count(j, "287") + Count(j, "723"),
              317u);
    EXPECT_EQ(Count(j, "41"), 25u);
    EXPECT_EQ(Count(j, "42"), 49u);
    EXPECT_EQ(Count(j, "48"), 49u);
    EXPECT_EQ(Count(j, "83"), 50u);
    EXPECT_EQ(Count(j, "140"), 46u);
    EXPECT_EQ(Count(j, "287"), 90u);
    EXPECT_EQ(Count(j, "723"), 8u);
    // The file ends inside a 28-byte header.
    const auto tail = j.at("truncated_tail_bytes").get<std::uint64_t>();
    EXPECT_GT(tail, 0u);
    EXPECT_LT(tail, 28u);
}

// ---- The program --------------------------------------------------------------------------

struct RunResult {
    int exit_code = -1;
    std::string output;
};

RunResult RunInspect(const std::string& args) {
    const std::string command = std::string(PITMAP_BIN_DIR) + "/pitmap-inspect " + args + " 2>&1";
    RunResult result;
    FILE* pipe = popen(command.c_str(), "r");
    if (pipe == nullptr) return result;
    char buf[4096];
    std::size_t n = 0;
    while ((n = std::fread(buf, 1, sizeof(buf), pipe)) > 0) result.output.append(buf, n);
    const int status = pclose(pipe);
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return result;
}

TEST(InspectProgramTest, JsonOutputEqualsGolden) {
    const std::string name = "swri_corrimudata.pcapng";
    const RunResult r = RunInspect("--json --dump-first 2 '" + (kDataDir / name).string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_EQ(json::parse(r.output, nullptr, false), ReadJson(kGoldenDir / (name + ".json")));
}

TEST(InspectProgramTest, TextOutputNamesMessages) {
    const RunResult r = RunInspect("'" + (kDataDir / "oem7drv_bestpos.gps").string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("BESTPOS"), std::string::npos);
    EXPECT_NE(r.output.find("INSPVAS"), std::string::npos);
}

TEST(InspectProgramTest, ErrorsNameTheFileAndExitNonZero) {
    const RunResult missing = RunInspect("--json does/not/exist.gps");
    EXPECT_NE(missing.exit_code, 0);
    EXPECT_NE(missing.output.find("does/not/exist.gps"), std::string::npos) << missing.output;

    const RunResult dir = RunInspect("'" + kDataDir.string() + "'");
    EXPECT_NE(dir.exit_code, 0);
    EXPECT_NE(dir.output.find("directory"), std::string::npos) << dir.output;

    const RunResult bad_format = RunInspect("--format nonsense x.gps");
    EXPECT_NE(bad_format.exit_code, 0);

    // A file that is none of the formats: refused with a message, never a crash.
    const fs::path garbage = fs::temp_directory_path() / "pitmap_inspect_regression_garbage.bin";
    {
        std::ofstream out(garbage, std::ios::binary);
        for (int i = 0; i < 5000; ++i) out.put(static_cast<char>((i * 7919) % 97 + 1));
    }
    const RunResult unknown = RunInspect("'" + garbage.string() + "'");
    EXPECT_EQ(unknown.exit_code, 1) << unknown.output;
    EXPECT_NE(unknown.output.find(garbage.string()), std::string::npos) << unknown.output;
    EXPECT_NE(unknown.output.find("cannot tell the format"), std::string::npos);
    // Forced to NovAtel framing, the same bytes are all garbage, and that is a report.
    const RunResult forced =
        RunInspect("--json --format raw --protocol novatel '" + garbage.string() + "'");
    EXPECT_EQ(forced.exit_code, 0) << forced.output;
    const json j = json::parse(forced.output, nullptr, false);
    ASSERT_TRUE(j.is_object()) << forced.output;
    EXPECT_EQ(j.at("frames_total"), 0);
    EXPECT_EQ(j.at("skipped_bytes").at("total"), 5000);
    fs::remove(garbage);
}

}  // namespace
}  // namespace pitmap::tools::inspect
