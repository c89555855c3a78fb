// SPDX-License-Identifier: MIT
#include "common/byte_io.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace pitmap {
namespace {

TEST(ByteReader, ReadsLittleAndBigEndian) {
    const std::vector<std::uint8_t> bytes = {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08};
    ByteReader le(bytes);
    EXPECT_EQ(le.U16Le(), 0x0201);
    EXPECT_EQ(le.U32Le(), 0x06050403u);
    EXPECT_EQ(le.U16Le(), 0x0807);
    EXPECT_TRUE(le.ok());
    EXPECT_EQ(le.remaining(), 0u);

    ByteReader be(bytes);
    EXPECT_EQ(be.U16Be(), 0x0102);
    EXPECT_EQ(be.U32Be(), 0x03040506u);
    EXPECT_EQ(be.U16Be(), 0x0708);
    ByteReader be64(bytes);
    EXPECT_EQ(be64.U64Be(), 0x0102030405060708ull);
    ByteReader le64(bytes);
    EXPECT_EQ(le64.U64Le(), 0x0807060504030201ull);
}

TEST(ByteReader, SignedValuesKeepTheirSign) {
    const std::vector<std::uint8_t> bytes = {0xFF, 0xFF, 0xFE, 0xFF, 0xFF, 0xFF, 0x80};
    ByteReader r(bytes);
    EXPECT_EQ(r.I16Le(), -1);
    EXPECT_EQ(r.I32Le(), -2);
    EXPECT_EQ(r.I8(), -128);
}

TEST(ByteReader, ReadPastEndFailsStickyWithoutMoving) {
    const std::vector<std::uint8_t> bytes = {0xAA, 0xBB, 0xCC};
    ByteReader r(bytes);
    EXPECT_EQ(r.U8(), 0xAA);
    EXPECT_EQ(r.U32Le(), 0u);  // only 2 left
    EXPECT_FALSE(r.ok());
    EXPECT_EQ(r.position(), 1u);
    // Sticky: even a read that would fit now fails.
    EXPECT_EQ(r.U8(), 0u);
    EXPECT_FALSE(r.ok());
    EXPECT_TRUE(r.Bytes(1).empty());
}

TEST(ByteReader, EmptyInputFailsEveryRead) {
    ByteReader r;
    EXPECT_EQ(r.F64Le(), 0.0);
    EXPECT_FALSE(r.ok());
    ByteReader r2;
    EXPECT_FALSE(r2.Skip(1));
    ByteReader r3;
    EXPECT_TRUE(r3.Seek(0));
    EXPECT_FALSE(r3.Seek(1));
}

TEST(ByteReader, SeekAndSkipStayInBounds) {
    const std::vector<std::uint8_t> bytes(10, 0x11);
    ByteReader r(bytes);
    EXPECT_TRUE(r.Seek(10));
    EXPECT_EQ(r.remaining(), 0u);
    EXPECT_TRUE(r.Seek(4));
    EXPECT_TRUE(r.Skip(6));
    EXPECT_FALSE(r.Skip(std::numeric_limits<std::size_t>::max()));
    EXPECT_FALSE(r.ok());
}

TEST(ByteReader, FixedStringStopsAtNulAndIgnoresJunkAfterIt) {
    const std::vector<std::uint8_t> bytes = {'A', 'B', 0, 'Z', 'q'};
    ByteReader r(bytes);
    EXPECT_EQ(r.FixedString(4), "AB");
    EXPECT_EQ(r.position(), 4u);
    EXPECT_EQ(r.FixedString(1), "q");
}

TEST(ByteWriterReader, FloatRoundTripBothOrders) {
    std::vector<std::uint8_t> buf;
    ByteWriter w(buf);
    w.F32Le(1.5f);
    w.F64Le(-2.25);
    w.F32Be(std::numeric_limits<float>::infinity());
    w.F64Be(3.0e-300);
    ASSERT_EQ(buf.size(), 24u);
    ByteReader r(buf);
    EXPECT_EQ(r.F32Le(), 1.5f);
    EXPECT_EQ(r.F64Le(), -2.25);
    EXPECT_TRUE(std::isinf(r.F32Be()));
    EXPECT_EQ(r.F64Be(), 3.0e-300);
    EXPECT_TRUE(r.ok());
}

TEST(ByteWriter, KnownFloatBytes) {
    std::vector<std::uint8_t> buf;
    ByteWriter w(buf);
    w.F32Be(1.0f);  // IEEE-754: 0x3F800000
    EXPECT_EQ(buf, (std::vector<std::uint8_t>{0x3F, 0x80, 0x00, 0x00}));
}

TEST(ByteWriter, FixedStringPadsAndTruncates) {
    std::vector<std::uint8_t> buf;
    ByteWriter w(buf);
    w.FixedString("83P", 5);
    w.FixedString("TOOLONG", 3);
    EXPECT_EQ(buf, (std::vector<std::uint8_t>{'8', '3', 'P', 0, 0, 'T', 'O', 'O'}));
}

TEST(ByteWriter, PatchInsideOnly) {
    std::vector<std::uint8_t> buf;
    ByteWriter w(buf);
    w.Zeros(4);
    EXPECT_TRUE(w.PatchU16Be(0, 0x1234));
    EXPECT_TRUE(w.PatchU16Le(2, 0x1234));
    EXPECT_EQ(buf, (std::vector<std::uint8_t>{0x12, 0x34, 0x34, 0x12}));
    EXPECT_FALSE(w.PatchU16Le(3, 1));
    EXPECT_FALSE(w.PatchU32Le(1, 1));
    EXPECT_FALSE(w.PatchU32Le(100, 1));
    EXPECT_TRUE(w.PatchU32Le(0, 0xA1B2C3D4u));
    EXPECT_EQ(buf, (std::vector<std::uint8_t>{0xD4, 0xC3, 0xB2, 0xA1}));
}

}  // namespace
}  // namespace pitmap
