// SPDX-License-Identifier: MIT
// NovAtel framing + CRC + decoding throughput (common/protocol/novatel), and allocations per
// frame in steady state (a counting global operator new).
//   pitmap-bench-novatel                  # MB/s as bytes_per_second, allocs_per_frame counter
// Streams: the real .gps captures concatenated many times; a synthetic INSPVAS/RAWIMUSX/BESTPOS
// stream made by the encoder. Both are pushed in 4 KiB chunks, as a serial/TCP reader would.
#include <benchmark/benchmark.h>

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <new>
#include <string>
#include <vector>

#include "common/protocol/novatel/decoder.hpp"
#include "common/protocol/novatel/encoder.hpp"
#include "common/protocol/novatel/framer.hpp"

namespace {
std::atomic<std::uint64_t> g_allocations{0};
}  // namespace

// The replaced global operator new below pairs malloc with free; GCC cannot see that the
// replacement is global and warns about a mismatch at inlined call sites.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

void* operator new(std::size_t n) {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
    std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
    std::free(p);
}

namespace {

namespace nv = pitmap::protocol::novatel;
using Bytes = std::vector<std::uint8_t>;

Bytes ReadCapture(const std::string& name) {
    std::ifstream in(std::string(PITMAP_TEST_DATA_DIR) + "/novatel/" + name, std::ios::binary);
    return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

const Bytes& RealStream() {
    static const Bytes stream = [] {
        const char* files[] = {"oem7drv_align.gps",
                               "oem7drv_bestpos.gps",
                               "oem7drv_ins1.gps",
                               "oem7drv_ins2.gps",
                               "oem7drv_ins2_humble.gps",
                               "oem7drv_rxstatus.gps",
                               "oem7drv_time.gps",
                               "rtklib_oemv_200911218.gps"};
        Bytes one;
        for (const char* f : files) {
            const Bytes b = ReadCapture(f);
            one.insert(one.end(), b.begin(), b.end());
        }
        Bytes out;
        while (out.size() < (16u << 20) && !one.empty())
            out.insert(out.end(), one.begin(), one.end());
        return out;
    }();
    return stream;
}

const Bytes& SyntheticStream() {
    static const Bytes stream = [] {
        Bytes out;
        out.reserve(17u << 20);
        nv::InsPva pva;
        pva.header.kind = nv::HeaderKind::kShortBinary;
        pva.header.message_id = nv::msg_id::kInsPvaS;
        pva.header.gps_week = 2218;
        pva.gps_week = 2218;
        pva.ins_status = nv::InsStatus::kSolutionGood;
        nv::RawImu imu;
        imu.header.kind = nv::HeaderKind::kShortBinary;
        imu.header.message_id = nv::msg_id::kRawImuSX;
        imu.imu_type = 41;
        imu.gps_week = 2218;
        nv::BestPos pos;
        pos.header.message_id = nv::msg_id::kBestPos;
        pos.header.time_status = nv::TimeStatus::kFineSteering;
        pos.header.gps_week = 2218;
        pos.position_type = nv::PositionType::kInsRtkFixed;
        // 200 Hz RAWIMUSX, 50 Hz INSPVAS, 1 Hz BESTPOS.
        for (std::uint32_t i = 0; out.size() < (16u << 20); ++i) {
            const double t = 500000.0 + i * 0.005;
            imu.gps_seconds = t;
            imu.header.gps_ms = static_cast<std::uint32_t>(t * 1000.0);
            imu.accel_counts = {static_cast<std::int64_t>(i % 100), -5, 6000};
            nv::EncodeBinary(imu, out);
            if (i % 4 == 0) {
                pva.gps_seconds = t;
                pva.header.gps_ms = imu.header.gps_ms;
                pva.latitude_deg = -23.0 + i * 1e-9;
                nv::EncodeBinary(pva, out);
            }
            if (i % 200 == 0) {
                pos.header.gps_ms = imu.header.gps_ms;
                nv::EncodeBinary(pos, out);
            }
        }
        return out;
    }();
    return stream;
}

void RunStream(benchmark::State& state, const Bytes& stream) {
    constexpr std::size_t kChunk = 4096;
    std::uint64_t frames = 0;
    std::uint64_t messages = 0;
    std::uint64_t allocations = 0;
    nv::Framer framer;
    for (auto _ : state) {
        const std::uint64_t alloc_before = g_allocations.load(std::memory_order_relaxed);
        for (std::size_t pos = 0; pos < stream.size(); pos += kChunk) {
            const std::size_t n = std::min(kChunk, stream.size() - pos);
            framer.Push(pitmap::ByteSpan(stream.data() + pos, n));
            while (true) {
                auto ev = framer.Next();
                if (std::holds_alternative<pitmap::protocol::NeedMore>(ev)) break;
                if (const auto* f = std::get_if<nv::Frame>(&ev)) {
                    ++frames;
                    const nv::DecodeResult r = nv::Decode(*f);
                    messages += nv::IsMessage(r) ? 1 : 0;
                    benchmark::DoNotOptimize(r);
                }
            }
        }
        benchmark::DoNotOptimize(framer.Flush());
        allocations += g_allocations.load(std::memory_order_relaxed) - alloc_before;
    }
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * stream.size()));
    state.counters["frames"] =
        static_cast<double>(frames) / static_cast<double>(state.iterations());
    state.counters["decoded"] =
        static_cast<double>(messages) / static_cast<double>(state.iterations());
    state.counters["allocs_per_frame"] =
        frames == 0 ? 0.0 : static_cast<double>(allocations) / static_cast<double>(frames);
}

void BM_RealCaptures(benchmark::State& state) {
    RunStream(state, RealStream());
}
void BM_SyntheticInsImu(benchmark::State& state) {
    RunStream(state, SyntheticStream());
}

void BM_FramingOnly(benchmark::State& state) {
    const Bytes& stream = SyntheticStream();
    nv::Framer framer;
    for (auto _ : state) {
        for (std::size_t pos = 0; pos < stream.size(); pos += 4096) {
            framer.Push(pitmap::ByteSpan(stream.data() + pos,
                                         std::min<std::size_t>(4096, stream.size() - pos)));
            while (!std::holds_alternative<pitmap::protocol::NeedMore>(framer.Next())) {
            }
        }
    }
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * stream.size()));
}

BENCHMARK(BM_RealCaptures)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SyntheticInsImu)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FramingOnly)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
