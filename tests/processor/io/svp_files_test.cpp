// SPDX-License-Identifier: MIT
// ReadSoundSpeedFiles (processor/io/svp_files.hpp) on eight real casts, one per probe format
// (tests/data/svp/, see its README): each recognised by content, its time and position, and
// the down cast the rule of processor/svp/probe_casts.hpp keeps. The expected values were read
// by hand from the files (line numbers below); depths from pressure and computed speeds go
// through the UNESCO functions tested in tests/processor/svp/seawater_test.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "common/gps_time.hpp"
#include "processor/io/svp_files.hpp"
#include "processor/svp/probe_casts.hpp"
#include "processor/svp/seawater.hpp"

namespace {

using namespace pitmap::proc;
namespace fs = std::filesystem;

const std::string kDir = std::string(PITMAP_TEST_DATA_DIR) + "/svp/";

std::int64_t GpsAt(int y, int mo, int d, int h, int mi, int s) {
    pitmap::UtcCalendar c;
    c.year = y;
    c.month = mo;
    c.day = d;
    c.hour = h;
    c.minute = mi;
    c.second = s;
    return pitmap::GpsFromUnix(*pitmap::UnixFromUtcCalendar(c));
}

struct Expect {
    std::size_t points;
    double first_depth_m, first_speed_mps, last_depth_m, last_speed_mps;
    std::int64_t utime_gps;
    double latitude_deg, longitude_deg;  // NaN: none in the file
};

svp::SoundSpeedCast ReadOne(const std::string& file) {
    const auto r = io::ReadSoundSpeedFiles({kDir + file});
    EXPECT_TRUE(r) << (r ? "" : r.error().message);
    if (!r || r->size() != 1) {
        ADD_FAILURE() << file << ": not one cast";
        return {};
    }
    EXPECT_TRUE(svp::ValidateCast(r->front()).empty()) << file;
    return r->front();
}

void Check(const std::string& file, const Expect& e, double tol = 1e-9) {
    SCOPED_TRACE(file);
    const svp::SoundSpeedCast c = ReadOne(file);
    ASSERT_EQ(c.depth_m.size(), e.points);
    EXPECT_NEAR(c.depth_m.front(), e.first_depth_m, tol);
    EXPECT_NEAR(c.speed_mps.front(), e.first_speed_mps, tol);
    EXPECT_NEAR(c.depth_m.back(), e.last_depth_m, tol);
    EXPECT_NEAR(c.speed_mps.back(), e.last_speed_mps, tol);
    EXPECT_EQ(c.utime_gps, e.utime_gps);
    if (std::isnan(e.latitude_deg)) {
        EXPECT_FALSE(c.has_position());
    } else {
        EXPECT_NEAR(c.latitude_deg, e.latitude_deg, 1e-9);
        EXPECT_NEAR(c.longitude_deg, e.longitude_deg, 1e-9);
    }
}

svp::CastFormat Sniff(const std::string& file) {
    std::ifstream in(kDir + file, std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return svp::SniffProbeFormat(text);
}

const double kNaN = std::nan("");

TEST(ProbeFiles, AmlBaseX2) {
    // [Data.X] Latitude=43.0733 Longitude=-70.7107 (its GPS) wins over [Instrument]'s 43.0738;
    // Date=2019-04-11 Time=18:25:00. Rows: speed, pressure (dbar), temperature; the down cast
    // is 0000.09 dbar 1451.274 m/s (first row) to 0009.28 dbar 1457.510 m/s (10th row), then
    // 9 rows up.
    EXPECT_EQ(Sniff("aml_025485_2019-04-11_18-25-00.csv"), svp::CastFormat::kAml);
    Check("aml_025485_2019-04-11_18-25-00.csv",
          {10,
           svp::DepthFromPressureUnesco(0.09, 43.0733),
           1451.274,
           svp::DepthFromPressureUnesco(9.28, 43.0733),
           1457.510,
           GpsAt(2019, 4, 11, 18, 25, 0),
           43.0733,
           -70.7107});
}

TEST(ProbeFiles, CastAway) {
    // '% Cast time (UTC),2012-08-21 12:28:17', start 43.0390326 -70.6471651; processed: 75
    // rows already one down cast (lines 31 and 105: depth and sound velocity columns).
    EXPECT_EQ(Sniff("castaway_11E101663_20120821_122817.csv"), svp::CastFormat::kCastAway);
    Check("castaway_11E101663_20120821_122817.csv",
          {75,
           0.14964919506734439,
           1512.6298657208513,
           22.356607253897842,
           1491.7460836757875,
           GpsAt(2012, 8, 21, 12, 28, 17),
           43.0390326,
           -70.6471651});
}

TEST(ProbeFiles, HypackVel) {
    // 'FTP NEW 3 37.998879852 -122.416305140 15:47 08/19/2019'; 36 rows, 1.6 m twice (the
    // second dropped by the thinning): 0.0 1504.92 to 54.2 1510.04.
    EXPECT_EQ(Sniff("hypack_20190819_SV_1549_D.vel"), svp::CastFormat::kHypackVel);
    Check("hypack_20190819_SV_1549_D.vel",
          {35,
           0.0,
           1504.92,
           54.2,
           1510.04,
           GpsAt(2019, 8, 19, 15, 47, 0),
           37.998879852,
           -122.416305140});
}

TEST(ProbeFiles, KongsbergAsvp) {
    // '( SoundVelocity 1.0 0 201203212242 22.50000000 -156.50000000 -1 0 0 OMS01_00000 P 0035 )'
    // 35 points, 0.00 1531.40 to the extension point 12000.00 1675.82.
    EXPECT_EQ(Sniff("kongsberg_20120321_224205.asvp"), svp::CastFormat::kKongsbergAsvp);
    Check("kongsberg_20120321_224205.asvp",
          {35, 0.0, 1531.40, 12000.0, 1675.82, GpsAt(2012, 3, 21, 22, 42, 0), 22.5, -156.5});
}

TEST(ProbeFiles, MvpS12) {
    // '$MVS12,00010,0061,220142,20,05,2017,0.33,1483.12,...' to '135.18,1483.33,...',
    // '4751.82,N,12224.13,W': 61 points, monotonic (a free-fall profiler, no soak).
    EXPECT_EQ(Sniff("mvp_MVP_2017-05-20_220137.s12"), svp::CastFormat::kSimradS12);
    Check("mvp_MVP_2017-05-20_220137.s12",
          {61,
           0.33,
           1483.12,
           135.18,
           1483.33,
           GpsAt(2017, 5, 20, 22, 1, 42),
           47.0 + 51.82 / 60.0,
           -(122.0 + 24.13 / 60.0)});
}

TEST(ProbeFiles, SeaBirdCnvSpeedFromCtd) {
    // Columns prdM (dbar), c0S/m, tv290C, flag: no sound speed, so Chen & Millero from PSS-78.
    // '* cast 2 07 Mar 2013 20:01:53' (instrument clock); no NMEA position. In air (lines
    // 144-207), soak at about 0.59 dbar (208-677), descent 678-741 (0.661 to 3.831 dbar:
    // lines 670-678 span 0.603-0.661 dbar < 0.1 m, the last still stretch), up cast 742-796.
    EXPECT_EQ(Sniff("seabird_SBE19Plus_CTP_2013_066_200153.cnv"), svp::CastFormat::kSeaBirdCnv);
    auto speed = [](double p, double c_s_m, double t) {
        return svp::SoundSpeedChenMillero(svp::SalinityFromConductivity(c_s_m * 10.0, t, p), t, p);
    };
    const double lat = 45.0;  // no position in the file
    Check("seabird_SBE19Plus_CTP_2013_066_200153.cnv",
          {64,
           svp::DepthFromPressureUnesco(0.661, lat),
           speed(0.661, 1.237811, 5.3614),
           svp::DepthFromPressureUnesco(3.831, lat),
           speed(3.831, 1.175774, 4.9175),
           GpsAt(2013, 3, 7, 20, 1, 53),
           kNaN,
           kNaN});
    // Brackish water at 5 degC: about 1440 m/s (salinity about 11).
    const svp::SoundSpeedCast c = ReadOne("seabird_SBE19Plus_CTP_2013_066_200153.cnv");
    ASSERT_FALSE(c.speed_mps.empty());
    EXPECT_NEAR(c.speed_mps.front(), 1442.7, 0.1);
    svp::ProbeCastStats st;
    std::ifstream in(kDir + "seabird_SBE19Plus_CTP_2013_066_200153.cnv");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_TRUE(svp::ParseProbeCast(text, "x.cnv", svp::CastFormat::kSeaBirdCnv, &st));
    EXPECT_EQ(st.rows, 653u);
    EXPECT_EQ(st.soak, 534u);  // lines 144-677
    EXPECT_EQ(st.up_cast, 55u);
    EXPECT_TRUE(st.speed_computed);
    EXPECT_TRUE(st.depth_from_pressure);
}

TEST(ProbeFiles, SimradS10) {
    // '$AAS10,00023,0706,011900,25,04,2009,0.70,1482.67,,,,' ... '12000.00,1685.31,,,,' '\':
    // 706 points, no position.
    EXPECT_EQ(Sniff("simrad_00023_091150119.ssp"), svp::CastFormat::kSimradS10);
    Check("simrad_00023_091150119.ssp",
          {706, 0.70, 1482.67, 12000.0, 1685.31, GpsAt(2009, 4, 25, 1, 19, 0), kNaN, kNaN});
}

TEST(ProbeFiles, ValeportMidas) {
    // 'Time Stamp : 05/04/2016 16:28:42' (5 April, day first); rows: speed, pressure (dbar).
    // Soak at 0.79-0.93 dbar (lines 39-98), descent from line 98 (0.932 dbar, 1423.175 m/s) to
    // line 134 (5.927 dbar, 1418.095 m/s), up cast, then 14 rows in air with speed 0.000.
    EXPECT_EQ(Sniff("valeport_midas_svx2_FILE2.000"), svp::CastFormat::kValeportMidas);
    Check("valeport_midas_svx2_FILE2.000",
          {35,
           svp::DepthFromPressureUnesco(0.932, 45.0),
           1423.175,
           svp::DepthFromPressureUnesco(5.927, 45.0),
           1418.095,
           GpsAt(2016, 4, 5, 16, 28, 42),
           kNaN,
           kNaN});
}

TEST(ProbeFiles, AllEightInOneCall) {
    std::vector<std::string> paths;
    for (const auto& e : fs::directory_iterator(kDir)) {
        const std::string n = e.path().filename().string();
        if (n != "README.md" && n.rfind("LICENSE", 0) != 0) paths.push_back(e.path().string());
    }
    ASSERT_EQ(paths.size(), 8u);
    const auto r = io::ReadSoundSpeedFiles(paths);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->size(), 8u);
}

TEST(ProbeFiles, UnknownFormatListsTheKnownOnes) {
    const fs::path tmp = fs::temp_directory_path() / "pitmap_svp_unknown.txt";
    {
        std::ofstream out(tmp);
        out << "Probe XYZ export v2\n0.5 1495\n";
    }
    const auto r = io::ReadSoundSpeedFiles({tmp.string()});
    fs::remove(tmp);
    ASSERT_FALSE(r);
    const std::string& m = r.error().message;
    EXPECT_NE(m.find(tmp.string()), std::string::npos) << m;
    EXPECT_NE(m.find("not a sound-velocity cast format"), std::string::npos) << m;
    for (const char* f : {"CARIS",
                          "AML",
                          "CastAway",
                          "HYPACK",
                          "Kongsberg",
                          "MVP",
                          "Sea-Bird",
                          "Simrad",
                          "Valeport"}) {
        EXPECT_NE(m.find(f), std::string::npos) << f << " in " << m;
    }
}

}  // namespace
