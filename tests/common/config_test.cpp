// SPDX-License-Identifier: MIT
#include "common/config.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

namespace pitmap {
namespace {

// A config in the project's style: defaults in class, Validate() lists every problem.
struct ExampleConfig {
    double voxel_size_m = 0.1;  // TSDF voxel edge, metres
    int port = 4040;            // UDP port
    std::string name = "demo";  // scenario name
    std::vector<double> lever_arm_m = {0, 0, 0};

    std::vector<std::string> Validate() const {
        std::vector<std::string> p;
        if (!(voxel_size_m > 0)) p.push_back("voxel_size_m must be > 0");
        if (port < 1 || port > 65535) p.push_back("port must be 1..65535");
        if (lever_arm_m.size() != 3) p.push_back("lever_arm_m must have 3 elements");
        return p;
    }
};

std::vector<std::string> Load(const std::string& yaml, ExampleConfig& cfg) {
    auto reader = ConfigReader::FromString(yaml, "test.yaml");
    if (!reader) return {reader.error().message};
    reader->Read("voxel_size_m", cfg.voxel_size_m);
    reader->Require("port", cfg.port);
    reader->Read("name", cfg.name);
    reader->Read("lever_arm_m", cfg.lever_arm_m);
    reader->RejectUnknownKeys();
    std::vector<std::string> problems = reader->problems();
    for (auto& p : cfg.Validate()) problems.push_back(p);
    return problems;
}

TEST(ConfigReader, ReadsValuesAndKeepsDefaults) {
    ExampleConfig cfg;
    const auto problems = Load("port: 5000\nlever_arm_m: [1.0, 2.0, -0.5]\n", cfg);
    EXPECT_TRUE(problems.empty()) << FormatProblems(problems);
    EXPECT_EQ(cfg.port, 5000);
    EXPECT_DOUBLE_EQ(cfg.voxel_size_m, 0.1);
    EXPECT_EQ(cfg.lever_arm_m, (std::vector<double>{1.0, 2.0, -0.5}));
}

TEST(ConfigReader, ListsEveryProblemAtOnce) {
    ExampleConfig cfg;
    const auto problems =
        Load("voxel_size_m: -1\nname: [a, b]\nlever_arm_m: [1, 2]\nvoxle_size: 3\n", cfg);
    // missing port, wrong type for name, unknown key, then Validate: voxel size, lever arm.
    ASSERT_EQ(problems.size(), 5u) << FormatProblems(problems);
    const std::string all = FormatProblems(problems);
    EXPECT_NE(all.find("port: required but missing"), std::string::npos);
    EXPECT_NE(all.find("test.yaml:2: name has the wrong type"), std::string::npos);
    EXPECT_NE(all.find("voxle_size is not a known setting"), std::string::npos);
    EXPECT_NE(all.find("voxel_size_m must be > 0"), std::string::npos);
    EXPECT_NE(all.find("lever_arm_m must have 3"), std::string::npos);
}

TEST(ConfigReader, SyntaxErrorNamesFileAndLine) {
    auto reader = ConfigReader::FromString("a: 1\nb: [1, 2\n", "bad.yaml");
    ASSERT_FALSE(reader.ok());
    EXPECT_NE(reader.error().message.find("bad.yaml:"), std::string::npos);
    EXPECT_NE(reader.error().message.find("YAML syntax error"), std::string::npos);
}

TEST(ConfigReader, TopLevelMustBeAMap) {
    EXPECT_FALSE(ConfigReader::FromString("- 1\n- 2\n").ok());
    EXPECT_TRUE(ConfigReader::FromString("").ok());  // empty file: all defaults
}

// Found by daemon_config_fuzz: a key that is a list or a map ("? -" is a complex key holding a
// list) threw YAML::TypedBadConversion out of RejectUnknownKeys. It is an unknown setting.
TEST(ConfigReader, ListAndMapKeysAreUnknownSettingsNotExceptions) {
    for (const char* text : {"? -\n", "? [a, b]\n: 1\n", "{x: 1}: 2\n", "sub:\n  ? [c]\n  : 3\n"}) {
        auto reader = ConfigReader::FromString(text, "keys.yaml");
        ASSERT_TRUE(reader.ok()) << text;
        ConfigReader sub = reader->Child("sub");
        EXPECT_NO_THROW(sub.RejectUnknownKeys()) << text;
        EXPECT_NO_THROW(reader->RejectUnknownKeys()) << text;
        ASSERT_FALSE(reader->problems().empty()) << text;
        EXPECT_NE(reader->problems().back().find("not a known setting"), std::string::npos)
            << reader->problems().back();
    }
}

TEST(ConfigReader, MissingFileIsAClearError) {
    auto reader = ConfigReader::FromFile("/nonexistent/pitmap.yaml");
    ASSERT_FALSE(reader.ok());
    EXPECT_NE(reader.error().message.find("cannot open"), std::string::npos);
}

TEST(ConfigReader, NestedMapsAndListsCarryTheirPath) {
    auto reader = ConfigReader::FromString(
        "daemon:\n  log_dir: /tmp\n  channels:\n    - name: a\n      port: 1\n    - name: b\n      "
        "prot: 2\n"
        "    - 7\n");
    ASSERT_TRUE(reader.ok());
    ConfigReader daemon = reader->Child("daemon");
    std::string log_dir;
    EXPECT_TRUE(daemon.Read("log_dir", log_dir));
    auto items = daemon.Items("channels");
    ASSERT_EQ(items.size(), 2u);
    for (auto& item : items) {
        std::string name;
        int port = 0;
        item.Require("name", name);
        item.Read("port", port);
        item.RejectUnknownKeys();
    }
    daemon.RejectUnknownKeys();
    reader->RejectUnknownKeys();
    const std::string all = FormatProblems(reader->problems());
    ASSERT_EQ(reader->problems().size(), 2u) << all;
    EXPECT_NE(all.find("daemon.channels[1].prot is not a known setting"), std::string::npos) << all;
    EXPECT_NE(all.find("daemon.channels[2]: must be a map"), std::string::npos) << all;
}

TEST(ConfigReader, ChildThatIsNotAMap) {
    auto reader = ConfigReader::FromString("sonar: 5\n");
    ASSERT_TRUE(reader.ok());
    ConfigReader sonar = reader->Child("sonar");
    int x = 3;
    EXPECT_FALSE(sonar.Read("x", x));
    EXPECT_EQ(x, 3);
    ASSERT_EQ(reader->problems().size(), 1u);
}

TEST(ConfigReader, MissingChildKeepsDefaultsAndDoesNotThrow) {
    auto reader = ConfigReader::FromString("a: 1\n");
    ASSERT_TRUE(reader.ok());
    ConfigReader missing = reader->Child("sonar");
    int x = 3;
    EXPECT_FALSE(missing.Read("x", x));
    EXPECT_EQ(x, 3);
    EXPECT_FALSE(missing.Has("x"));
    EXPECT_TRUE(missing.Keys().empty());
    EXPECT_TRUE(missing.Items("list").empty());
    missing.Child("deeper").RejectUnknownKeys();
    missing.RejectUnknownKeys();
    EXPECT_FALSE(missing.Require("port", x));
    ASSERT_EQ(reader->problems().size(), 1u);
    EXPECT_NE(reader->problems()[0].find("sonar.port: required but missing"), std::string::npos)
        << reader->problems()[0];
}

TEST(ConfigReader, FromFileReadsWhatWasWritten) {
    const std::string path = ::testing::TempDir() + "/pitmap_config_test.yaml";
    {
        std::ofstream out(path);
        out << "port: 7\n";
    }
    auto reader = ConfigReader::FromFile(path);
    ASSERT_TRUE(reader.ok());
    int port = 0;
    EXPECT_TRUE(reader->Require("port", port));
    EXPECT_EQ(port, 7);
    std::remove(path.c_str());
}

}  // namespace
}  // namespace pitmap
