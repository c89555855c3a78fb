// SPDX-License-Identifier: MIT
// The probe readers (processor/svp/probe_casts.hpp) on crafted and damaged inputs: the
// down-cast rule on synthetic series, truncated and corrupted copies of the real casts
// (tests/data/svp/) as errors naming the file and line, and the computed speed against the
// probe maker's own (Valeport's "Calc. SOS" column).
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "processor/svp/cast.hpp"
#include "processor/svp/probe_casts.hpp"
#include "processor/svp/seawater.hpp"

namespace {

using namespace pitmap::proc::svp;

std::string ReadData(const std::string& file) {
    std::ifstream in(std::string(PITMAP_TEST_DATA_DIR) + "/svp/" + file, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// The first `n` lines of a text.
std::string Head(const std::string& text, int n) {
    std::size_t pos = 0;
    for (int i = 0; i < n && pos != std::string::npos; ++i) {
        pos = text.find('\n', pos);
        if (pos != std::string::npos) ++pos;
    }
    return pos == std::string::npos ? text : text.substr(0, pos);
}

void ExpectError(const std::string& text, const std::string& where, const std::string& what) {
    const auto r = ParseCastText(text, "f.x");
    ASSERT_FALSE(r) << text.substr(0, 200);
    EXPECT_NE(r.error().message.find(where), std::string::npos) << r.error().message;
    EXPECT_NE(r.error().message.find(what), std::string::npos) << r.error().message;
}

TEST(DownCast, SoakDescentUpCast) {
    // In air, a soak at 1 m (still for more than 8 samples), a descent with a wiggle, the up cast.
    const std::vector<double> d = {0.0, 0.0, 0.5, 1.0, 1.01, 0.99, 1.0, 1.02, 1.0, 0.98, 1.0, 1.01,
                                   1.0, 1.5, 2.0, 1.9, 2.5,  3.0,  3.0, 4.0,  3.5, 2.0,  1.0, 0.0};
    ProbeCastStats st;
    const auto keep = DownCast(d, &st);
    // The last still stretch ends at index 12 (samples 4..12 span 0.04 m); the deepest is 19.
    const std::vector<std::size_t> want = {12, 13, 14, 16, 17, 19};
    EXPECT_EQ(keep, want);
    EXPECT_EQ(st.soak, 12u);
    EXPECT_EQ(st.up_cast, 4u);
    EXPECT_EQ(st.thinned, 2u);  // 1.9 (shallower than 2.0) and the second 3.0
}

TEST(DownCast, StillDeepInTheCastIsNotASoak) {
    // A winch stop at 8 m of a 10 m cast (lower half) stays in the descent.
    std::vector<double> d;
    for (int i = 0; i <= 16; ++i) d.push_back(0.5 * i);
    for (int i = 0; i < 12; ++i) d.push_back(8.0 + 0.001 * (i % 2));
    for (int i = 1; i <= 4; ++i) d.push_back(8.0 + 0.5 * i);
    const auto keep = DownCast(d, nullptr);
    EXPECT_EQ(keep.front(), 0u);
    EXPECT_DOUBLE_EQ(d[keep.back()], 10.0);
    for (std::size_t i = 1; i < keep.size(); ++i) EXPECT_GT(d[keep[i]], d[keep[i - 1]]);
}

TEST(DownCast, EditedProfileUnchanged) {
    const std::vector<double> d = {0.0, 1.0, 2.0, 5.0, 10.0};
    EXPECT_EQ(DownCast(d, nullptr).size(), 5u);
    EXPECT_TRUE(DownCast({}, nullptr).empty());
}

TEST(ProbeCasts, ChenMilleroAgreesWithValeportsOwnSpeed) {
    // Valeport MIDAS rows (line 98 and 134 of the real file): T, C (mS/cm), P (dbar), and the
    // probe software's "Calc. SALINITY" and "Calc. SOS" (EOS-80). Ours agree to 0.01 psu and
    // 0.05 m/s: the same equations.
    struct Row {
        double t, c, p, sal, sos;
    };
    for (const Row& r :
         {Row{3.244, 4.604, 0.932, 4.308, 1423.817}, Row{1.735, 5.468, 5.927, 5.428, 1418.277}}) {
        const double s = SalinityFromConductivity(r.c, r.t, r.p);
        EXPECT_NEAR(s, r.sal, 0.01);
        EXPECT_NEAR(SoundSpeedChenMillero(s, r.t, r.p), r.sos, 0.05);
    }
}

TEST(ProbeCasts, TruncatedFilesAreErrors) {
    // Each real file cut short: an error naming the file (and the line when there is one).
    ExpectError(Head(ReadData("kongsberg_20120321_224205.asvp"), 20), "f.x", "declares 35");
    ExpectError(Head(ReadData("mvp_MVP_2017-05-20_220137.s12"), 30), "f.x", "truncated");
    ExpectError(Head(ReadData("simrad_00023_091150119.ssp"), 300), "f.x", "truncated");
    ExpectError(
        Head(ReadData("seabird_SBE19Plus_CTP_2013_066_200153.cnv"), 100), "f.x", "no '*END*'");
    ExpectError(Head(ReadData("aml_025485_2019-04-11_18-25-00.csv"), 40), "f.x", "no [data]");
    ExpectError(
        Head(ReadData("castaway_11E101663_20120821_122817.csv"), 20), "f.x", "no column header");
    ExpectError(Head(ReadData("valeport_midas_svx2_FILE2.000"), 20), "f.x", "no 'Date / Time'");
    // A row cut in the middle.
    const std::string cnv = ReadData("seabird_SBE19Plus_CTP_2013_066_200153.cnv");
    ExpectError(cnv.substr(0, cnv.size() - 20), "f.x:796:", "a truncated row");
    const std::string vp = ReadData("valeport_midas_svx2_FILE2.000");
    ExpectError(Head(vp, 60) + "05/04/2016 16:34:54\t1423.385\t0.7",
                "f.x:61:",
                "fields, the column header (line 32)");
    const std::string ca = ReadData("castaway_11E101663_20120821_122817.csv");
    ExpectError(Head(ca, 40) + "0.15,0.149", "f.x:41:", "fields, the column header (line 29)");
}

TEST(ProbeCasts, CorruptedValuesNameTheLine) {
    ExpectError("FTP NEW 3 37.9 -122.4 15:47 08/19/2019\n0.0 1504.92\n1.2 15O4.9\n",
                "f.x:3:",
                "sound speed '15O4.9' is not a number");
    ExpectError("FTP NEW 3 97.9 -122.4 15:47 08/19/2019\n0.0 1504.92\n", "f.x:1:", "position");
    ExpectError("FTP NEW 3 37.9 -122.4 25:47 08/19/2019\n0.0 1504.92\n", "f.x:1:", "time");
    ExpectError("( SoundVelocity 1.0 0 2012032122 22.5 -156.5 -1 0 0 X P 0001 )\n0 1500\n",
                "f.x:1:",
                "YYYYMMDDHHMM");
    ExpectError("$AAS10,00023,0002,011900,25,04,2009,0.70,1482.67,,,,\n1.30,x,,,,\n\\\n",
                "f.x:2:",
                "sound speed 'x'");
    ExpectError("$AAS10,00023,0002,016000,25,04,2009,0.70,1482.67,,,,\n1.30,1490,,,,\n\\\n",
                "f.x:1:",
                "time");
    ExpectError(
        "$MVS12,1,0001,220142,20,05,2017,0.33,1483.12,12.4,22.2,\n4751.82,Q,12224.13,W,"
        "0.0,AML*76\n\\\n",
        "f.x:2:",
        "position");
    std::string aml = ReadData("aml_025485_2019-04-11_18-25-00.csv");
    aml.replace(aml.find("1457.401"), 8, "1457,401");
    ExpectError(aml, "f.x:100:", "6 fields, the first row (line 99) has 5");
    std::string vp = ReadData("valeport_midas_svx2_FILE2.000");
    vp.replace(vp.find("05/04/2016 16:34:43"), 10, "35/14/2016");
    ExpectError(vp, "f.x:34:", "DD/MM/YYYY");
    std::string cnv = ReadData("seabird_SBE19Plus_CTP_2013_066_200153.cnv");
    cnv.replace(cnv.find("0.661   1.237811"), 16, "0.661   1.2#7811");
    ExpectError(cnv, "f.x:678:", "'1.2#7811' is not a number");
    ExpectError("* Sea-Bird\n# nquan = 2\n# name 0 = c0S/m: C\n# name 1 = flag: f\n*END*\n1 0\n",
                "f.x",
                "no depth");
}

TEST(ProbeCasts, ShortTimeFieldsAreErrors) {
    // Found by the fuzz target: a time field shorter than its layout (no exception).
    ExpectError("$AAS10,011900,25,04,2009,0.70,1482.67,,,,\n1.3,1480,,,,\n\\\n", "f.x:1:", "time");
    ExpectError("( SoundVelocity 1.0 0 20 22.5 -156.5 -1 0 0 X P 0001 )\n0 1500\n",
                "f.x:1:",
                "YYYYMMDDHHMM");
}

TEST(ProbeCasts, AllRowsImplausibleIsAnError) {
    ExpectError("FTP NEW 3\n0.0 0.0\n1.0 0.0\n", "f.x", "none of the 2 rows");
}

TEST(ProbeCasts, SeaBirdFlagsAndNmeaHeader) {
    // NMEA position and time win; flagged and bad-flag rows are dropped; depth column used.
    const std::string cnv =
        "* Sea-Bird SBE 9 Data File:\n"
        "* NMEA Latitude = 40 26.61 N\n"
        "* NMEA Longitude = 007 46.83 W\n"
        "* NMEA UTC (Time) = Jun 15 2026 09:00:05\n"
        "# nquan = 4\n"
        "# name 0 = depSM: Depth [salt water, m]\n"
        "# name 1 = svCM: Sound Velocity [Chen-Millero, m/s]\n"
        "# name 2 = t090C: Temperature\n"
        "# name 3 = flag:  0.000e+00\n"
        "# bad_flag = -9.990e-29\n"
        "*END*\n"
        "  0.5 1480.0 10.0 0\n"
        "  1.0 -9.990e-29 10.0 0\n"
        "  1.5 1479.0 10.0 1\n"
        "  2.0 1478.0 10.0 0\n";
    ProbeCastStats st;
    const auto r = ParseProbeCast(cnv, "a.cnv", SniffProbeFormat(cnv), &st);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(st.format, CastFormat::kSeaBirdCnv);
    EXPECT_EQ(st.invalid, 2u);
    EXPECT_FALSE(st.speed_computed);
    EXPECT_EQ(r->depth_m, (std::vector<double>{0.5, 2.0}));
    EXPECT_NEAR(r->latitude_deg, 40 + 26.61 / 60, 1e-12);
    EXPECT_NEAR(r->longitude_deg, -(7 + 46.83 / 60), 1e-12);
    EXPECT_TRUE(r->has_time());
}

}  // namespace
