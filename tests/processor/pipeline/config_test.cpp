// SPDX-License-Identifier: MIT
// The processor config's key table (processor/pipeline/config.cpp): what `config --defaults`
// prints reads back to the defaults, a config with every section changed reads back to itself,
// and unknown keys, wrong types and invalid values are all listed at once.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "processor/hydro/datum.hpp"
#include "processor/pipeline/pipeline.hpp"

namespace pitmap::proc::pipeline {
namespace {

namespace fs = std::filesystem;

class Config : public ::testing::Test {
protected:
    void SetUp() override {
        path_ = (fs::path(::testing::TempDir()) /
                 ("pitmap_config_" + std::to_string(::getpid()) + ".yaml"))
                    .string();
    }
    void TearDown() override { fs::remove(path_); }
    Expected<PipelineConfig> Load(const std::string& yaml) {
        std::ofstream(path_, std::ios::trunc) << yaml;
        return LoadConfig(path_);
    }
    std::string path_;
};

// Every value of the config that the table covers, as text, to compare two configs.
std::string Fingerprint(const PipelineConfig& c) {
    return ConfigYaml(c);
}

TEST_F(Config, DefaultsReadBackToTheDefaults) {
    const auto c = Load(DefaultsYaml());
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_EQ(Fingerprint(*c), Fingerprint(PipelineConfig{}));
    EXPECT_FALSE(c->ingest.sonar_clock_offset_known) << "null keeps the offset unknown";
    EXPECT_TRUE(std::isnan(c->origin_latitude_deg));
    // Every section is printed.
    const std::string d = DefaultsYaml();
    for (const char* section : {"\ningest:\n",
                                "\ngeoref:\n",
                                "\ncalibrate:\n",
                                "\nslam:\n",
                                "\nfuse:\n",
                                "\nmesh:\n",
                                "\nrun:\n",
                                "\nquality:\n",
                                "\nproducts:\n",
                                "\n  origin:\n"}) {
        EXPECT_NE(d.find(section), std::string::npos) << section;
    }
}

// A value changed in every section (of every kind: bool, int, double, string, enum, nullable)
// is printed and read back: the reader and the printer visit the same keys.
TEST_F(Config, EverySectionRoundTripsThroughTheTable) {
    PipelineConfig c;
    c.ingest.source = io::IngestSource::kRaw;
    c.ingest.nav_channel_id = "novatel_com1";
    c.ingest.sonar_clock_offset_s = -2.5;
    c.ingest.sonar_clock_offset_known = true;
    c.ingest.require_good_ins = true;
    c.georef.max_range_m = 77.5;
    c.georef.spike_half_window = 5;
    c.calibrate.beam_stride = 7;
    c.calibrate.estimate_latency = false;
    c.calibrate.latency_scan_step_s = 0.025;
    c.slam.correspondence = slam::CorrespondenceType::kGicp;
    c.slam.robust_kernel = slam::RobustKernel::kHuber;
    c.slam_stage.point_stride = 3;
    c.tsdf.sensor_model = fusion::SensorModel::kRay;
    c.tsdf.voxel_size_m = 0.2;
    c.weight_filter.min_weight = 2.5;
    c.mesh.max_hole_edges = 11;
    c.run.slam = false;
    c.quality.slam_max_fraction = 0.25;
    c.write_las = false;
    c.write_rejected = false;
    c.vehicle_yaml = "some dir/vehicle: \"a\".yaml";
    c.origin_latitude_deg = 40.123456789;
    c.origin_longitude_deg = -7.5;
    c.origin_height_m = 412.25;
    ASSERT_TRUE(c.Validate().empty());
    const std::string yaml = ConfigYaml(c);
    ASSERT_NE(yaml, ConfigYaml(PipelineConfig{}));
    const auto back = Load(yaml);
    ASSERT_TRUE(back.ok()) << back.error().message << "\n" << yaml;
    EXPECT_EQ(Fingerprint(*back), yaml);
    EXPECT_TRUE(back->ingest.sonar_clock_offset_known);
    EXPECT_EQ(back->ingest.sonar_clock_offset_s, -2.5);
    EXPECT_EQ(back->ingest.source, io::IngestSource::kRaw);
    EXPECT_EQ(back->slam.correspondence, slam::CorrespondenceType::kGicp);
    EXPECT_EQ(back->vehicle_yaml, c.vehicle_yaml);
    EXPECT_FALSE(back->write_rejected);
    EXPECT_EQ(back->origin_latitude_deg, 40.123456789);
    EXPECT_EQ(back->calibrate.beam_stride, 7);
}

// Every problem is listed, in every section (ingest, georef and calibrate included), with the
// file and the key.
TEST_F(Config, EveryProblemIsListed) {
    const auto r = Load(
        "ingest:\n  source: sideways\n  colour: red\n"
        "georef:\n  max_range_m: far\n  bogus: 1\n"
        "calibrate:\n  beam_stride: 1.5\n  estimate_latency: maybe\n"
        "slam:\n  robust_kernel: tukey\n"
        "fuse:\n  voxel_size_m: -1\n"
        "run:\n  initial_mesh_voxel_factor: 0.5\n  initial_mesh_ping_stride: 0\n"
        "products:\n  origin:\n    latitude_deg: 40\n    altitude: 3\n"
        "extra_section: {}\n");
    ASSERT_FALSE(r.ok());
    const std::string& m = r.error().message;
    for (const char* expected :
         {"ingest.source: 'sideways' is not one of auto, decoded, raw",
          "ingest.colour",
          "georef.max_range_m",
          "georef.bogus",
          "calibrate.beam_stride",
          "calibrate.estimate_latency",
          "slam.robust_kernel: 'tukey' is not one of none, huber, cauchy",
          "products.origin.altitude",
          "extra_section",
          "fuse.voxel_size_m",
          "run.initial_mesh_voxel_factor must be within 1..8",
          "run.initial_mesh_ping_stride must be within 1..8",
          "products.origin needs latitude_deg, longitude_deg and height_m"}) {
        EXPECT_NE(m.find(expected), std::string::npos) << expected << "\n" << m;
    }
    EXPECT_NE(m.find(path_), std::string::npos) << m;
}

// The vertical datum and S-44 sections (issue 17): round trip, and their problems listed.
TEST_F(Config, VerticalAndS44SectionsRoundTripAndAreChecked) {
    const auto r = Load(
        "vertical:\n  datum: water_level\n  water_level_source: file\n"
        "  water_level_file: gauge.csv\n  ins_height_above_waterline_m: 0.4\n"
        "s44:\n  order: special\n  crossing_angle_deg: 60\n  enabled: false\n");
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->grid.vertical.datum, hydro::VerticalDatum::kWaterLevel);
    EXPECT_EQ(r->grid.vertical.water_level_source, hydro::WaterLevelSource::kFile);
    EXPECT_EQ(r->grid.vertical.water_level_file, "gauge.csv");
    EXPECT_EQ(r->grid.vertical.ins_height_above_waterline_m, 0.4);
    EXPECT_EQ(r->grid.s44_config.order, hydro::S44Order::kSpecial);
    EXPECT_EQ(r->grid.s44_config.crossing_angle_deg, 60);
    EXPECT_FALSE(r->grid.s44);
    const auto back = Load(ConfigYaml(*r));
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(Fingerprint(*back), ConfigYaml(*r));
    const std::string defaults = DefaultsYaml();
    EXPECT_NE(defaults.find("vertical:\n  datum: ellipsoid"), std::string::npos) << defaults;
    EXPECT_NE(defaults.find("s44:\n  enabled: true"), std::string::npos) << defaults;
    const auto bad = Load(
        "vertical:\n  datum: chart\n  geoid_vertical_epsg: 4326\n  smoothing_window_s: -1\n"
        "s44:\n  order: 3\n  crossing_angle_deg: 120\n");
    ASSERT_FALSE(bad.ok());
    for (const char* expected :
         {"vertical.datum: 'chart' is not one of ellipsoid, geoid, water_level",
          "s44.order: '3' is not one of exclusive, special, 1a, 1b, 2",
          "vertical.smoothing_window_s must be within",
          "s44.crossing_angle_deg must be in (0, 90]"}) {
        EXPECT_NE(bad.error().message.find(expected), std::string::npos) << expected << "\n"
                                                                         << bad.error().message;
    }
    const auto geoid = Load("vertical:\n  datum: geoid\n  geoid_vertical_epsg: 4326\n");
    ASSERT_FALSE(geoid.ok());
    EXPECT_NE(geoid.error().message.find("vertical.geoid_vertical_epsg 4326"), std::string::npos);
    const auto file = Load("vertical:\n  datum: water_level\n  water_level_source: file\n");
    ASSERT_FALSE(file.ok());
    EXPECT_NE(file.error().message.find("vertical.water_level_file is needed"), std::string::npos);
}

// The mosaic section (issue 17 item 6): round trip, defaults printed, problems listed.
TEST_F(Config, MosaicSectionRoundTripsAndIsChecked) {
    const auto r = Load(
        "mosaic:\n  angular: lambert\n  spreading_db_per_decade: 30\n"
        "  absorption_db_per_m: 0.05\n  reference_angle_deg: 40\n  enabled: false\n");
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->grid.mosaic_config.angular, hydro::AngularCorrection::kLambert);
    EXPECT_EQ(r->grid.mosaic_config.spreading_db_per_decade, 30);
    EXPECT_EQ(r->grid.mosaic_config.absorption_db_per_m, 0.05);
    EXPECT_EQ(r->grid.mosaic_config.reference_angle_deg, 40);
    EXPECT_FALSE(r->grid.mosaic);
    const auto back = Load(ConfigYaml(*r));
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(Fingerprint(*back), ConfigYaml(*r));
    const std::string defaults = DefaultsYaml();
    EXPECT_NE(defaults.find("mosaic:\n  enabled: true"), std::string::npos) << defaults;
    EXPECT_NE(defaults.find("angular: empirical"), std::string::npos) << defaults;
    EXPECT_NE(defaults.find("absorption_db_per_m: 0.021"), std::string::npos) << defaults;
    const auto bad =
        Load("mosaic:\n  angular: phong\n  spreading_db_per_decade: -3\n  max_incidence_deg: 95\n");
    ASSERT_FALSE(bad.ok());
    for (const char* expected : {"mosaic.angular: 'phong' is not one of none, lambert, empirical",
                                 "mosaic.spreading_db_per_decade must be within 0..80",
                                 "mosaic.max_incidence_deg must be within 10..89"}) {
        EXPECT_NE(bad.error().message.find(expected), std::string::npos) << expected << "\n"
                                                                         << bad.error().message;
    }
}

// Issue 38: the memory budget and the block size of the block-wise parts are read, written
// back, and a block that does not fit in the budget is an error at start naming both keys.
TEST_F(Config, MemoryBudgetRoundTripsAndABlockMustFitInIt) {
    const auto r = Load("run:\n  memory_budget_mb: 1500\n  block_soundings: 65536\n");
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->run.memory_budget_mb, 1500);
    EXPECT_EQ(r->run.block_soundings, 65536);
    const auto back = Load(ConfigYaml(*r));
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(Fingerprint(*back), ConfigYaml(*r));
    EXPECT_NE(DefaultsYaml().find("memory_budget_mb: 4096"), std::string::npos);
    EXPECT_TRUE(PipelineConfig{}.Validate().empty()) << "the defaults fit";
    // 2^21 soundings at 64 bytes = 128 MB: more than a 100 MB budget; exactly 64 MB fits 64 MB.
    const auto big = Load("run:\n  memory_budget_mb: 100\n  block_soundings: 2097152\n");
    ASSERT_FALSE(big.ok());
    EXPECT_NE(big.error().message.find("run.block_soundings: one block of 2097152 soundings (128 "
                                       "MB at 64 bytes a sounding) does not fit in "
                                       "run.memory_budget_mb (100 MB)"),
              std::string::npos)
        << big.error().message;
    const auto exact = Load("run:\n  memory_budget_mb: 64\n  block_soundings: 1048576\n");
    EXPECT_TRUE(exact.ok()) << exact.error().message;
    const auto one_more = Load("run:\n  memory_budget_mb: 64\n  block_soundings: 1048577\n");
    EXPECT_FALSE(one_more.ok());
    const auto tiny = Load("run:\n  memory_budget_mb: 10\n  block_soundings: 100\n");
    ASSERT_FALSE(tiny.ok());
    for (const char* expected :
         {"run.memory_budget_mb must be >= 64", "run.block_soundings must be >= 1024"}) {
        EXPECT_NE(tiny.error().message.find(expected), std::string::npos) << expected << "\n"
                                                                          << tiny.error().message;
    }
}

TEST(Stage, NamesAreSummaryJsonKeys) {
    EXPECT_STREQ(ToString(Stage::kFuse), "fuse");
    EXPECT_STREQ(ToString(Stage::kMeshInitial), "mesh_initial");
    EXPECT_STREQ(ToString(Stage::kExport), "export");
}

// The metadata section (issue 39): read back, printed with the defaults, every problem listed
// (an S-44 order pitmap does not know, control characters, more lines than a header field
// holds, over-long values), and what the products say from it (BuildProductMetadata,
// summary.json's schema: every text field a string, EPSG codes int or null).
TEST_F(Config, MetadataSectionIsReadValidatedAndWritten) {
    const auto r = Load(
        "metadata:\n  project: Bejanca 2026\n  client: Mina\n  site: Bejanca\n"
        "  survey_id: BJ-7\n  surveyor: A. Surveyor\n  organisation: Pit Survey\n"
        "  s44_order_target: special\n  notes: \"line 1\\nline 2\"\n");
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->metadata.project, "Bejanca 2026");
    EXPECT_EQ(r->metadata.site, "Bejanca");
    EXPECT_EQ(r->metadata.s44_order_target, "special");
    EXPECT_EQ(r->metadata.notes, "line 1\nline 2");
    const auto back = Load(ConfigYaml(*r));
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(Fingerprint(*back), Fingerprint(*r));
    EXPECT_NE(DefaultsYaml().find("metadata:\n  project: \"\""), std::string::npos)
        << DefaultsYaml();

    const auto bad = Load(
        "metadata:\n  s44_order_target: 3a\n  project: \"a\\tb\"\n"
        "  site: \"two\\nlines\"\n  client: \"" +
        std::string(kMaxMetadataChars + 1, 'x') + "\"\n  owner: me\n");
    ASSERT_FALSE(bad.ok());
    for (const char* expected : {"metadata.s44_order_target \"3a\" is not an IHO S-44 order",
                                 "metadata.project must be one line without control characters",
                                 "metadata.site must be one line",
                                 "metadata.client is 501 characters, more than 500",
                                 "metadata.owner"}) {
        EXPECT_NE(bad.error().message.find(expected), std::string::npos) << expected << "\n"
                                                                         << bad.error().message;
    }

    VehicleDescription v;
    v.name = "asv-1";
    v.sonar_model = "Imagenex Delta T";
    v.ins_model = "NovAtel SPAN";
    hydro::DatumModel egm;
    egm.crs_name = "EGM96 height";
    egm.vertical_epsg = 5773;
    egm.description = "EGM96";
    MetadataInputs in;
    in.vehicle = &v;
    // 2026-06-15T09:00:00 UTC in GPS microseconds (18 leap seconds).
    in.first_ping_utime_gps = 1'465'549'218LL * 1'000'000;
    in.last_ping_utime_gps = *in.first_ping_utime_gps + 3'661'500'000LL;
    in.gps_minus_utc_s = 18;
    in.processed_unix_us = 1'800'000'000LL * 1'000'000;
    in.utm_zone = 29;
    in.datum = &egm;
    const ProductMetadata m = BuildProductMetadata(r->metadata, in);
    const nlohmann::json j = MetadataJson(m);
    EXPECT_EQ(j["vessel"], "asv-1") << "vessel unset: the vehicle's name";
    EXPECT_EQ(j["survey_start_utc"], "2026-06-15T09:00:00Z");
    EXPECT_EQ(j["survey_end_utc"], "2026-06-15T10:01:01Z");
    EXPECT_EQ(j["processed_utc"], "2027-01-15T08:00:00Z");
    ASSERT_EQ(j["equipment"].size(), 2u);
    EXPECT_EQ(j["equipment"][0]["role"], "multibeam");
    EXPECT_EQ(j["equipment"][1]["model"], "NovAtel SPAN");
    EXPECT_EQ(j["horizontal_crs"]["epsg"], 32629);
    EXPECT_EQ(j["vertical_crs"]["epsg"], 5773);
    EXPECT_EQ(j["s44_order_target"], "special");
    EXPECT_EQ(j["software"].get<std::string>().rfind("pitmap ", 0), 0u);
    // Unset: "" for text, null for codes and the order; no key absent.
    const nlohmann::json e = MetadataJson(BuildProductMetadata(SurveyMetadataConfig{}, {}));
    for (const char* k : {"project",
                          "client",
                          "site",
                          "survey_id",
                          "surveyor",
                          "organisation",
                          "vessel",
                          "notes",
                          "survey_start_utc",
                          "survey_end_utc",
                          "processed_utc"}) {
        ASSERT_TRUE(e.contains(k)) << k;
        EXPECT_EQ(e[k], "") << k;
    }
    EXPECT_TRUE(e["horizontal_crs"]["epsg"].is_null());
    EXPECT_TRUE(e["vertical_crs"]["epsg"].is_null());
    EXPECT_EQ(e["vertical_crs"]["name"], "WGS 84 ellipsoidal height");
    EXPECT_TRUE(e["s44_order_target"].is_null());
    EXPECT_TRUE(e["equipment"].empty());
}

}  // namespace
}  // namespace pitmap::proc::pipeline
