// SPDX-License-Identifier: MIT
// Where to cut a byte stream when a test feeds a framer in pieces: the style guide's parser
// matrix (whole, split at every offset, byte by byte, random chunks), written once for every
// framer's tests. A cut is an offset in [0, size]: one piece ends there, the next starts.
#pragma once

#include <cstddef>
#include <random>
#include <vector>

namespace pitmap::test {

// Cuts after every byte: 1, 2, ..., size - 1 (byte by byte).
inline std::vector<std::size_t> EveryByteCuts(std::size_t size) {
    std::vector<std::size_t> cuts;
    for (std::size_t i = 1; i < size; ++i) cuts.push_back(i);
    return cuts;
}

// Cuts at random offsets, pieces of 1..max_piece bytes.
inline std::vector<std::size_t> RandomCuts(std::size_t size,
                                           std::size_t max_piece,
                                           std::mt19937& rng) {
    std::vector<std::size_t> cuts;
    std::uniform_int_distribution<std::size_t> piece(1, max_piece);
    for (std::size_t at = piece(rng); at < size; at += piece(rng)) cuts.push_back(at);
    return cuts;
}

// The lengths of the pieces that the cuts (ascending) make of `size` bytes; empty pieces (a cut
// at 0, at size or twice at one offset) are dropped.
inline std::vector<std::size_t> PieceSizes(const std::vector<std::size_t>& cuts, std::size_t size) {
    std::vector<std::size_t> pieces;
    std::size_t from = 0;
    for (const std::size_t cut : cuts) {
        if (cut > from && cut < size) pieces.push_back(cut - from);
        if (cut > from) from = cut < size ? cut : size;
    }
    if (size > from) pieces.push_back(size - from);
    return pieces;
}

// Calls check(cuts, label) once for a single cut at every offset 0..size (split in two
// everywhere, the empty halves included).
template <class Check>
void ForEverySingleCut(std::size_t size, Check&& check) {
    for (std::size_t cut = 0; cut <= size; ++cut) check(std::vector<std::size_t>{cut}, cut);
}

}  // namespace pitmap::test
