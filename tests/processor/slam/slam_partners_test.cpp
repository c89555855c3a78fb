// SPDX-License-Identifier: MIT
// The bounded partner rule of SLAM's pair search (PartnerBlocks, docs/decisions/015): a query
// point is paired only with the max_partner_passes passes over its cell nearest in time on
// each side among those at least t_d away, however many passes the survey makes over it; a
// pass is a run of consecutive blocks listed in the cell.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

#include "processor/slam/internal.hpp"

namespace pitmap::proc::slam::detail {
namespace {

// Blocks of 10 s: block i spans [10 i, 10 i + 9.9] s.
std::vector<Block> TenSecondBlocks(std::size_t n) {
    std::vector<Block> blocks(n);
    for (std::size_t i = 0; i < n; ++i) {
        blocks[i].t0 = 10.0 * static_cast<double>(i);
        blocks[i].t1 = blocks[i].t0 + 9.9;
    }
    return blocks;
}

// A cell seen by `passes` passes of two blocks each, one every five blocks: pass j is blocks
// 5 j and 5 j + 1.
std::vector<std::uint32_t> CellOfPasses(std::uint32_t passes) {
    std::vector<std::uint32_t> listed;
    for (std::uint32_t j = 0; j < passes; ++j) {
        listed.push_back(5 * j);
        listed.push_back(5 * j + 1);
    }
    return listed;
}

TEST(SlamPartners, NearestPassesInTimeOnEachSide) {
    const std::vector<Block> blocks = TenSecondBlocks(40);
    const std::vector<std::uint32_t> listed = CellOfPasses(8);
    std::vector<std::uint32_t> partners;
    // A query at 205 s in block 20 (pass 4), t_d 30 s: blocks ending by 175 s and starting from
    // 235 s are far enough; two passes each side.
    PartnerBlocks(blocks, listed, 20, 205.0, 30.0, 2, partners);
    EXPECT_EQ(partners, (std::vector<std::uint32_t>{10, 11, 15, 16, 25, 26, 30, 31}));
    PartnerBlocks(blocks, listed, 20, 205.0, 30.0, 1, partners);
    EXPECT_EQ(partners, (std::vector<std::uint32_t>{15, 16, 25, 26}));
    // 0: every pass far enough in time (the seed paper's rule).
    PartnerBlocks(blocks, listed, 20, 205.0, 30.0, 0, partners);
    EXPECT_EQ(partners,
              (std::vector<std::uint32_t>{0, 1, 5, 6, 10, 11, 15, 16, 25, 26, 30, 31, 35, 36}));
}

TEST(SlamPartners, BlocksWithinTdAreSkippedAndCutAPassShort) {
    const std::vector<Block> blocks = TenSecondBlocks(40);
    // Pass 3 is blocks 15, 16, 17: block 17 ends at 179.9 s, within 30 s of a query at 205 s,
    // so the pass keeps 15 and 16 and still counts as one. Later, block 23 starts at 230 s,
    // within t_d: its pass {23, 24} keeps 24 only.
    const std::vector<std::uint32_t> listed = {5, 6, 10, 11, 15, 16, 17, 20, 23, 24, 30, 31};
    std::vector<std::uint32_t> partners;
    PartnerBlocks(blocks, listed, 20, 205.0, 30.0, 1, partners);
    EXPECT_EQ(partners, (std::vector<std::uint32_t>{15, 16, 24}));
    PartnerBlocks(blocks, listed, 20, 205.0, 30.0, 2, partners);
    EXPECT_EQ(partners, (std::vector<std::uint32_t>{10, 11, 15, 16, 24, 30, 31}));
}

TEST(SlamPartners, EdgesOfTheSurveyAndEmptyCells) {
    const std::vector<Block> blocks = TenSecondBlocks(40);
    const std::vector<std::uint32_t> listed = CellOfPasses(8);
    std::vector<std::uint32_t> partners = {99};  // cleared first
    // The first pass has nothing before it: only the passes after.
    PartnerBlocks(blocks, listed, 0, 5.0, 30.0, 2, partners);
    EXPECT_EQ(partners, (std::vector<std::uint32_t>{5, 6, 10, 11}));
    // The last: only the passes before.
    PartnerBlocks(blocks, listed, 35, 355.0, 30.0, 2, partners);
    EXPECT_EQ(partners, (std::vector<std::uint32_t>{25, 26, 30, 31}));
    PartnerBlocks(blocks, {}, 20, 205.0, 30.0, 2, partners);
    EXPECT_TRUE(partners.empty());
    // A query's own block need not be listed (its point may lie in the cell's margin).
    PartnerBlocks(blocks, listed, 18, 185.0, 30.0, 1, partners);
    EXPECT_EQ(partners, (std::vector<std::uint32_t>{10, 11, 25, 26}));
}

// However many passes see the cell, a query gets at most max_partner_passes passes a side,
// the same ones every call, and the nearest in time.
TEST(SlamPartners, BoundedByTheConfigAndDeterministic) {
    for (const std::uint32_t passes : {4u, 16u, 64u, 256u}) {
        const std::vector<Block> blocks = TenSecondBlocks(5 * passes);
        const std::vector<std::uint32_t> listed = CellOfPasses(passes);
        for (const int k : {1, 2, 3}) {
            for (std::uint32_t j = 0; j < passes; j += 3) {
                const std::uint32_t own = 5 * j;
                const double t = blocks[own].t0 + 5.0;
                std::vector<std::uint32_t> a, b;
                PartnerBlocks(blocks, listed, own, t, 30.0, k, a);
                PartnerBlocks(blocks, listed, own, t, 30.0, k, b);
                EXPECT_EQ(a, b);
                // Two blocks per pass; k passes before (if there are) and after.
                const std::size_t before = std::min<std::size_t>(j, k);
                const std::size_t after = std::min<std::size_t>(passes - 1 - j, k);
                ASSERT_EQ(a.size(), 2 * (before + after)) << passes << " passes, k " << k;
                for (const std::uint32_t bi : a) {
                    const double gap = bi < own ? t - blocks[bi].t1 : blocks[bi].t0 - t;
                    EXPECT_GE(gap, 30.0);
                    // The nearest passes: the k-th is 50 k s away (and the length of a block).
                    EXPECT_LE(gap, 50.0 * k + 10.0);
                }
            }
        }
    }
}

// The normal-fit neighbour tables (decision 032): each block-local index in as many bits as the
// block's point count needs, a slot in whole words; every index and the end marker come back
// as written, at the sizes where an index crosses a word or takes one more bit.
TEST(SlamNeighbourTables, PackedSlotsGiveBackWhatWasWritten) {
    std::mt19937_64 rng(11);
    for (const std::size_t count : {std::size_t{1},
                                    std::size_t{2},
                                    std::size_t{3},
                                    std::size_t{65535},
                                    std::size_t{65536},
                                    std::size_t{72000},
                                    std::size_t{131071},
                                    std::size_t{1} << 31}) {
        Block b;
        b.p0 = 1000;
        b.p1 = 1000 + count;
        for (const std::size_t k : {std::size_t{3},
                                    std::size_t{10},
                                    std::size_t{24},
                                    std::size_t{kMaxNormalNeighbours}}) {
            const NeighbourPacking pk(b, k);
            ASSERT_EQ(pk.none, count);
            ASSERT_LT(std::uint64_t{count} >> pk.bits, 1u) << count;  // the marker fits
            ASSERT_GE(std::uint64_t{count}, std::uint64_t{1} << (pk.bits - 1)) << count;
            ASSERT_EQ(pk.words, (k * static_cast<std::size_t>(pk.bits) + 63) / 64);
            for (const std::size_t n : {std::size_t{0}, k / 2, k}) {
                std::vector<std::size_t> idx(k);
                std::uniform_int_distribution<std::size_t> u(0, count - 1);
                for (std::size_t j = 0; j < n; ++j) idx[j] = j % 3 == 0 ? count - 1 : u(rng);
                std::vector<std::uint64_t> words(2 * pk.words, 0);  // two slots side by side
                pk.Pack(idx.data(), n, words.data() + pk.words);
                pk.Pack(idx.data(), k, words.data());
                std::uint32_t first[kMaxNormalNeighbours], second[kMaxNormalNeighbours];
                pk.Unpack(words.data(), first);
                pk.Unpack(words.data() + pk.words, second);
                for (std::size_t j = 0; j < k; ++j) {
                    EXPECT_EQ(first[j], idx[j]) << count << " " << k << " " << j;
                    EXPECT_EQ(second[j], j < n ? idx[j] : count) << count << " " << k << " " << j;
                }
            }
        }
    }
}

}  // namespace
}  // namespace pitmap::proc::slam::detail
