// SPDX-License-Identifier: MIT
// The vehicle description (vehicle.yaml, schema 1): the documented template and the written
// file read back; a foreign file, an old pitmap layout and a file without the sonar lever arm
// are errors naming what is missing; every other problem is listed; the mount rotations.
#include "common/vehicle.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/frames.hpp"

namespace pitmap {
namespace {

constexpr const char* kMinimal =
    "pitmap_vehicle: 1\n"
    "sonar:\n"
    "  lever_arm_m: [0.8, 0.0, 0.25]\n"
    "  mount: {orientation: down, connector: aft}\n";

std::string ErrorOf(const std::string& text) {
    auto v = ParseVehicleYaml(text, "v.yaml");
    return v ? std::string("(accepted)") : v.error().message;
}

bool Contains(const std::string& text, const std::string& what) {
    return text.find(what) != std::string::npos;
}

TEST(VehicleFile, TemplateParsesAndEveryKeyHasAComment) {
    const std::string t = VehicleYamlTemplate();
    auto v = ParseVehicleYaml(t, "template");
    ASSERT_TRUE(v) << v.error().message;
    EXPECT_EQ(v->sonar_lever_arm_m, Eigen::Vector3d(0.95, 0.0, 0.62));
    ASSERT_EQ(v->gnss_antenna_lever_arms_m.size(), 1u);
    ASSERT_TRUE(v->ins_height_above_waterline_m.has_value());
    EXPECT_FALSE(v->sonar_clock_offset_s.has_value());
    ASSERT_TRUE(v->uncertainty.has_value());
    EXPECT_EQ(v->uncertainty->heading_sigma_deg, SensorErrorModel{}.heading_sigma_deg);
    for (const char* key : {"pitmap_vehicle:",
                            "lever_arm_m:",
                            "orientation:",
                            "tilt_deg:",
                            "connector:",
                            "boresight_deg:",
                            "clock_offset_s:",
                            "sound_velocity_source:",
                            "antenna_lever_arms_m:",
                            "height_above_waterline_m:",
                            "range_sigma_m:",
                            "latency_sigma_s:",
                            "boresight_sigma_deg:"}) {
        // The line that sets the key (not a comment that names it).
        std::istringstream lines(t);
        bool found = false;
        for (std::string line; std::getline(lines, line);) {
            const auto first = line.find_first_not_of(' ');
            if (first == std::string::npos || line.compare(first, std::strlen(key), key) != 0) {
                continue;
            }
            found = true;
            EXPECT_NE(line.find('#'), std::string::npos) << key << " uncommented";
        }
        EXPECT_TRUE(found) << key;
    }
    // The clock-offset sign is stated in words.
    EXPECT_TRUE(Contains(t, "the sonar's (.83P header) clock minus GPS-disciplined UTC")) << t;
    EXPECT_TRUE(Contains(t, "> 0 = the sonar clock is ahead of UTC, < 0 = behind")) << t;
}

TEST(VehicleFile, WrittenFileReadsBackTheSameValues) {
    VehicleDescription v;
    v.name = "roaz \"2\"\n\tC:\\";
    v.sonar_lever_arm_m = Eigen::Vector3d(0.95, -0.1, 0.62);
    v.orientation = SonarOrientation::kTilted;
    v.tilt_deg = -35.5;
    v.connector = ConnectorDirection::kStarboard;
    v.boresight_deg = Eigen::Vector3d(0.1, -0.2, 1.0 / 3.0);
    v.sonar_clock_offset_s = 3602.37;
    v.sound_velocity_source = SoundVelocitySource::kProbe;
    v.sonar_channel = "deltat";
    v.gnss_antenna_lever_arms_m = {Eigen::Vector3d(0.42, -0.31, -1.25),
                                   Eigen::Vector3d(-0.58, -0.31, -1.25)};
    v.ins_height_above_waterline_m = 0.35;
    v.navigation_channel = "novatel_com1";
    v.sonar_model = "Imagenex Delta T 837B";
    v.ins_model = "NovAtel SPAN CPT7";
    const std::string text = FormatVehicleYaml(v);
    auto r = ParseVehicleYaml(text, "written");
    ASSERT_TRUE(r) << r.error().message << "\n" << text;
    EXPECT_EQ(r->name, v.name);
    EXPECT_EQ(r->sonar_lever_arm_m, v.sonar_lever_arm_m);
    EXPECT_EQ(r->orientation, v.orientation);
    EXPECT_EQ(r->tilt_deg, v.tilt_deg);
    EXPECT_EQ(r->connector, v.connector);
    EXPECT_EQ(r->boresight_deg, v.boresight_deg);  // exact: shortest round-trip text
    EXPECT_EQ(r->sonar_clock_offset_s, v.sonar_clock_offset_s);
    EXPECT_EQ(r->sound_velocity_source, v.sound_velocity_source);
    EXPECT_EQ(r->sonar_channel, v.sonar_channel);
    EXPECT_EQ(r->gnss_antenna_lever_arms_m, v.gnss_antenna_lever_arms_m);
    EXPECT_EQ(r->ins_height_above_waterline_m, v.ins_height_above_waterline_m);
    EXPECT_EQ(r->sonar_model, v.sonar_model);  // issue 39: the products' equipment
    EXPECT_EQ(r->ins_model, v.ins_model);
    EXPECT_EQ(r->navigation_channel, v.navigation_channel);
    // Indented, as a daemon config's `vehicle` section.
    const std::string section = FormatVehicleYaml(v, 2);
    EXPECT_EQ(section.rfind("  pitmap_vehicle: 1\n", 0), 0u) << section;
}

TEST(VehicleFile, UncertaintySectionIsOptionalAndReadsBack) {
    // Absent (every file before the section existed): the defaults.
    auto plain = ParseVehicleYaml(kMinimal, "v.yaml");
    ASSERT_TRUE(plain) << plain.error().message;
    EXPECT_FALSE(plain->uncertainty.has_value());
    EXPECT_EQ(plain->ErrorModel().range_sigma_m, SensorErrorModel{}.range_sigma_m);
    EXPECT_EQ(FormatVehicleYaml(*plain).find("uncertainty"), std::string::npos);
    // Partial: the keys given, the rest default.
    auto partial = ParseVehicleYaml(std::string(kMinimal) +
                                        "uncertainty:\n  range_sigma_m: 0.05\n"
                                        "  heading_sigma_deg: 0.1\n",
                                    "v.yaml");
    ASSERT_TRUE(partial) << partial.error().message;
    ASSERT_TRUE(partial->uncertainty.has_value());
    EXPECT_EQ(partial->uncertainty->range_sigma_m, 0.05);
    EXPECT_EQ(partial->uncertainty->heading_sigma_deg, 0.1);
    EXPECT_EQ(partial->uncertainty->roll_pitch_sigma_deg, SensorErrorModel{}.roll_pitch_sigma_deg);
    // Written and read back.
    VehicleDescription v = *plain;
    SensorErrorModel m;
    m.range_sigma_m = 0.011;
    m.range_sigma_fraction = 1.0 / 3000.0;
    m.beam_angle_sigma_deg = 0;
    m.latency_sigma_s = 0.0025;
    m.boresight_sigma_deg = 0.07;
    v.uncertainty = m;
    auto back = ParseVehicleYaml(FormatVehicleYaml(v), "written");
    ASSERT_TRUE(back) << back.error().message;
    ASSERT_TRUE(back->uncertainty.has_value());
    EXPECT_EQ(back->uncertainty->range_sigma_m, m.range_sigma_m);
    EXPECT_EQ(back->uncertainty->range_sigma_fraction, m.range_sigma_fraction);
    EXPECT_EQ(back->uncertainty->beam_angle_sigma_deg, 0.0);
    EXPECT_EQ(back->uncertainty->latency_sigma_s, m.latency_sigma_s);
    EXPECT_EQ(back->uncertainty->boresight_sigma_deg, m.boresight_sigma_deg);
    // Bad values and unknown keys are problems, each named.
    const std::string e = ErrorOf(std::string(kMinimal) +
                                  "uncertainty:\n  range_sigma_m: -1\n"
                                  "  range_sigma_fraction: 0.5\n  roll_sigma: 1\n");
    EXPECT_TRUE(Contains(e, "uncertainty.range_sigma_m")) << e;
    EXPECT_TRUE(Contains(e, "uncertainty.range_sigma_fraction")) << e;
    EXPECT_TRUE(Contains(e, "roll_sigma")) << e;
    EXPECT_TRUE(SensorErrorModel{}.Validate().empty());
    SensorErrorModel bad;
    bad.heave_sigma_m = std::nan("");
    EXPECT_EQ(bad.Validate().size(), 1u);
}

TEST(VehicleFile, MinimalFileHasTheStandardMount) {
    auto v = ParseVehicleYaml(kMinimal, "v.yaml");
    ASSERT_TRUE(v) << v.error().message;
    EXPECT_EQ(v->boresight_deg, Eigen::Vector3d::Zero());
    EXPECT_FALSE(v->sonar_clock_offset_s);
    EXPECT_TRUE(v->R_vehicle_sonar().isApprox(Eigen::Matrix3d::Identity()));
}

TEST(VehicleFile, ForeignFileIsNotAVehicleFileAndSaysWhatIsMissing) {
    // A ROS-style description someone left beside the logs.
    const std::string e = ErrorOf("robot: boat\nlinks:\n  - {name: base_link}\n");
    EXPECT_TRUE(Contains(e, "v.yaml: not a pitmap vehicle file")) << e;
    EXPECT_TRUE(Contains(e,
                         "missing: pitmap_vehicle sonar.lever_arm_m sonar.mount.orientation "
                         "sonar.mount.connector"))
        << e;
    EXPECT_TRUE(Contains(e, "pitmap config --vehicle")) << e;
    EXPECT_EQ(ErrorOf(""), ErrorOf("{}"));
    EXPECT_TRUE(Contains(ErrorOf("[1, 2]"), "v.yaml")) << ErrorOf("[1, 2]");
    EXPECT_TRUE(Contains(ErrorOf("a: [1,"), "v.yaml:")) << ErrorOf("a: [1,");
}

TEST(VehicleFile, OldPitmapLayoutsAreNamedWithTheirFix) {
    // pitmap-sim before schema 1, and pitmap-acqd's roaz.yaml section before schema 1.
    for (const char* old : {"vehicle: demo-asv\nlever_arms_m:\n  sonar: [0.8, 0.0, 0.25]\n"
                            "boresight_deg: [0.0, 0.0, 0.0]\nnavigation_channel: novatel_com1\n",
                            "name: ROAZ\nlever_arms_m:\n  imu_to_sonar: [0.95, 0.00, 0.62]\n"
                            "boresight_sonar_deg: {roll: 0, pitch: 0, yaw: 0}\n"}) {
        const std::string e = ErrorOf(old);
        EXPECT_TRUE(Contains(e, "not a pitmap vehicle file; missing: pitmap_vehicle")) << e;
        EXPECT_TRUE(Contains(e, "move the sonar lever arm to sonar.lever_arm_m")) << e;
    }
}

TEST(VehicleFile, MissingSonarLeverArmIsAnError) {
    const std::string e =
        ErrorOf("pitmap_vehicle: 1\nsonar:\n  mount: {orientation: down, connector: aft}\n");
    EXPECT_TRUE(Contains(e, "v.yaml: sonar.lever_arm_m: required but missing")) << e;
    const std::string no_sonar = ErrorOf("pitmap_vehicle: 1\nname: x\n");
    EXPECT_TRUE(Contains(no_sonar, "sonar.lever_arm_m: required but missing")) << no_sonar;
    EXPECT_TRUE(Contains(no_sonar, "sonar.mount.orientation: required but missing")) << no_sonar;
    EXPECT_TRUE(Contains(no_sonar, "sonar.mount.connector: required but missing")) << no_sonar;
}

TEST(VehicleFile, EveryProblemIsListedWithItsLine) {
    const std::string e = ErrorOf(
        "pitmap_vehicle: 2\n"                                   // 1
        "sonar:\n"                                              // 2
        "  lever_arm_m: [0.8, 0.0]\n"                           // 3
        "  mount:\n"                                            // 4
        "    orientation: sideways\n"                           // 5
        "    connector: aft\n"                                  // 6
        "    tilt_deg: 20\n"                                    // 7
        "  boresight_deg: [0, 0, 180]\n"                        // 8
        "  clock_offset_s: abc\n"                               // 9
        "  sound_velocity_source: ctd\n"                        // 10
        "gnss: {antenna_lever_arms_m: [[1, 2, 3], [1, 2]]}\n"   // 11
        "ins: {height_above_waterline_m: .nan, colour: red}\n"  // 12
        "lever_arms_m: {sonar: [0, 0, 0]}\n");                  // 13
    for (const char* what : {"pitmap_vehicle: schema 2 is not known",
                             "sonar.lever_arm_m: must be 3 finite numbers",
                             "sonar.mount.orientation: 'sideways' is not one of down | tilted",
                             "v.yaml:9: sonar.clock_offset_s has the wrong type",
                             "sonar.sound_velocity_source: 'ctd' is not one of",
                             "gnss.antenna_lever_arms_m[1]: must be 3 finite numbers",
                             "ins.height_above_waterline_m: must be a finite number",
                             "v.yaml:12: ins.colour is not a known setting",
                             "v.yaml:13: lever_arms_m is not a known setting",
                             "sonar.boresight_deg: [0, 0, 180] beyond +-15 degrees"}) {
        EXPECT_TRUE(Contains(e, what)) << what << " not in:\n" << e;
    }
    // A tilt needs the tilted orientation, and a tilted mount needs its tilt.
    EXPECT_TRUE(
        Contains(ErrorOf(std::string(kMinimal) + "  boresight_deg: [0, 0, 0]\n"), "(accepted)"));
    EXPECT_TRUE(Contains(ErrorOf("pitmap_vehicle: 1\nsonar:\n  lever_arm_m: [0, 0, 0]\n"
                                 "  mount: {orientation: down, connector: aft, tilt_deg: 30}\n"),
                         "sonar.mount.tilt_deg: 30 with orientation: down"));
    EXPECT_TRUE(Contains(ErrorOf("pitmap_vehicle: 1\nsonar:\n  lever_arm_m: [0, 0, 0]\n"
                                 "  mount: {orientation: tilted, connector: aft}\n"),
                         "sonar.mount.tilt_deg: required for orientation: tilted"));
    EXPECT_TRUE(Contains(ErrorOf("pitmap_vehicle: 1\nsonar:\n  lever_arm_m: [0, 0, 0]\n"
                                 "  mount: {orientation: tilted, connector: aft, tilt_deg: 95}\n"),
                         "0 < |tilt| <= 90"));
}

// The issue-34 layouts a surveyor mistypes: a lever arm in cm or mm, the sign of z flipped.
// Each is a problem that names the key, the value and the likely mistake; the real layouts
// (the simulator's, the template's, ROAZ's) are accepted.
TEST(VehicleFile, LayoutsNoSurfaceVehicleHasAreProblemsNamingTheMistake) {
    const auto with = [](const std::string& arm, const std::string& more = "") {
        return ErrorOf("pitmap_vehicle: 1\nsonar:\n  lever_arm_m: " + arm +
                       "\n  mount: {orientation: down, connector: aft}\n" + more);
    };
    const std::string water = "ins: {height_above_waterline_m: 0.0}\n";
    EXPECT_EQ(with("[0.8, 0.0, 0.25]", water), "(accepted)");
    EXPECT_EQ(with("[0.95, 0.0, 0.62]", "ins: {height_above_waterline_m: 0.35}\n"), "(accepted)");
    EXPECT_EQ(with("[0.8, 0.0, -0.25]"), "(accepted)");  // no water line: INS low in the hull

    // Sign of z flipped: the transducer above the water line.
    const std::string flipped = with("[-0.8, 0, -0.25]", water);
    EXPECT_TRUE(Contains(flipped,
                         "sonar.lever_arm_m: [-0.8, 0, -0.25] puts the transducer 0.25 "
                         "m above the water line"))
        << flipped;
    EXPECT_TRUE(Contains(flipped, "is its sign flipped?")) << flipped;
    // Without the water line: only far above the INS is a sign.
    EXPECT_TRUE(Contains(with("[0.8, 0, -3]"), "3 m above the INS")) << with("[0.8, 0, -3]");

    // z in centimetres: 25 m under the water.
    const std::string cm = with("[0.8, 0, 25]", water);
    EXPECT_TRUE(Contains(cm, "puts the transducer 25 m below the water line")) << cm;
    EXPECT_TRUE(Contains(cm, "z in centimetres? 25 cm is 0.25 m")) << cm;
    // The whole arm in millimetres.
    const std::string mm = with("[800, 0, 250]", water);
    EXPECT_TRUE(Contains(mm, "sonar.lever_arm_m: [800, 0, 250] is beyond 50 m")) << mm;
    EXPECT_TRUE(Contains(mm, "or in millimetres ([0.8, 0, 0.25] m)?")) << mm;
    const std::string cm_all = with("[80, 0, 25]", water);
    EXPECT_TRUE(Contains(cm_all, "in centimetres ([0.8, 0, 0.25] m)")) << cm_all;

    // GNSS antennas: in bounds, and above the water.
    const std::string antenna =
        with("[0.8, 0, 0.25]",
             water + "gnss: {antenna_lever_arms_m: [[-0.5, 0, 1.2], [0, 0, -1200]]}\n");
    EXPECT_TRUE(Contains(antenna,
                         "gnss.antenna_lever_arms_m[0]: [-0.5, 0, 1.2] puts the antenna "
                         "1.2 m below the water line"))
        << antenna;
    EXPECT_TRUE(Contains(antenna, "gnss.antenna_lever_arms_m[1]: [0, 0, -1200] is beyond 50 m"))
        << antenna;
}

TEST(VehicleFile, MissingFileIsNamed) {
    auto v = ReadVehicleFile("/nonexistent/vehicle.yaml");
    ASSERT_FALSE(v);
    EXPECT_EQ(v.error().message, "/nonexistent/vehicle.yaml: cannot open");
}

// Where the sonar's axes point in the vehicle frame (FRD) for each mount.
TEST(VehicleFile, MountOrientationsRotateTheSonarFrame) {
    struct Case {
        SonarOrientation orientation;
        double tilt_deg;
        ConnectorDirection connector;
        Eigen::Vector3d sonar_y_in_vehicle;  // the fan's positive-angle side
        Eigen::Vector3d sonar_z_in_vehicle;  // the centre beam
    };
    const double s30 = std::sin(frames::DegToRad(30)), c30 = std::cos(frames::DegToRad(30));
    const Case cases[] = {
        {SonarOrientation::kDown, 0, ConnectorDirection::kAft, {0, 1, 0}, {0, 0, 1}},
        {SonarOrientation::kDown, 0, ConnectorDirection::kForward, {0, -1, 0}, {0, 0, 1}},
        {SonarOrientation::kDown, 0, ConnectorDirection::kPort, {-1, 0, 0}, {0, 0, 1}},
        {SonarOrientation::kDown, 0, ConnectorDirection::kStarboard, {1, 0, 0}, {0, 0, 1}},
        // Tilted 30 deg towards the sonar's +y: the centre beam looks down and to starboard.
        {SonarOrientation::kTilted, 30, ConnectorDirection::kAft, {0, c30, -s30}, {0, s30, c30}},
        // Connector forward, tilted -30 (towards the sonar's -y = the vehicle's starboard).
        {SonarOrientation::kTilted,
         -30,
         ConnectorDirection::kForward,
         {0, -c30, s30},
         {0, s30, c30}},
        {SonarOrientation::kTilted, 90, ConnectorDirection::kPort, {0, 0, -1}, {-1, 0, 0}},
    };
    for (const Case& c : cases) {
        VehicleDescription v;
        v.orientation = c.orientation;
        v.tilt_deg = c.tilt_deg;
        v.connector = c.connector;
        const Eigen::Matrix3d R = v.R_vehicle_sonar();
        const std::string label =
            std::string(ToString(c.orientation)) + " " + ToString(c.connector);
        EXPECT_TRUE(R.col(1).isApprox(c.sonar_y_in_vehicle, 1e-12)) << label << "\n" << R;
        EXPECT_TRUE(R.col(2).isApprox(c.sonar_z_in_vehicle, 1e-12)) << label << "\n" << R;
        EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    }
    // The boresight turns about the vehicle's axes after the mount: a roll of the same sign
    // moves the centre beam the same way whichever way the connector points.
    VehicleDescription aft, fwd;
    aft.boresight_deg = fwd.boresight_deg = Eigen::Vector3d(2, 0, 0);
    fwd.connector = ConnectorDirection::kForward;
    EXPECT_TRUE(aft.R_vehicle_sonar().col(2).isApprox(fwd.R_vehicle_sonar().col(2), 1e-12));
    EXPECT_LT(aft.R_vehicle_sonar()(1, 2), 0);  // roll > 0: the beam swings to port
}

}  // namespace
}  // namespace pitmap
