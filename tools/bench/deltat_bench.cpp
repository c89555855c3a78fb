// SPDX-License-Identifier: MIT
// Imagenex Delta T 83P throughput: StreamFramer + DecodeRecord83PInto over a synthetic stream
// of 480-beam records (spec imagenex_deltat.md §1.2-1.3), with and without intensities.
// Reports bytes/s and heap allocations per record in steady state (a counting global
// operator new; the framer and the Ping83P are warmed up before timing).
#include <benchmark/benchmark.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <vector>

#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/deltat/stream_framer.hpp"

namespace {

std::atomic<std::uint64_t> g_allocations{0};

// Out of line so the compiler does not pair an inlined malloc/free with new/delete.
[[gnu::noinline]] void* Acquire(std::size_t size) {
    return std::malloc(size == 0 ? 1 : size);
}
[[gnu::noinline]] void Release(void* p) noexcept {
    std::free(p);
}

}  // namespace

void* operator new(std::size_t size) {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    if (void* p = Acquire(size)) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t size) {
    return operator new(size);
}
void operator delete(void* p) noexcept {
    Release(p);
}
void operator delete[](void* p) noexcept {
    Release(p);
}
void operator delete(void* p, std::size_t) noexcept {
    Release(p);
}
void operator delete[](void* p, std::size_t) noexcept {
    Release(p);
}

namespace {

using namespace pitmap;
using namespace pitmap::protocol;
using namespace pitmap::protocol::deltat;

constexpr std::size_t kRecordsPerStream = 256;
constexpr std::size_t kChunkBytes = 65536;  // one large socket/file read

std::vector<std::uint8_t> MakeStream(bool intensity) {
    std::vector<std::uint8_t> stream;
    for (std::size_t k = 0; k < kRecordsPerStream; ++k) {
        Ping83P p;
        p.format_version = kVersion110;
        SetHeaderTime(p, 1709646307678000 + static_cast<std::int64_t>(k) * 100000);
        SetHeaderLatitude(p, -23.5);
        SetHeaderLongitude(p, 133.25);
        p.start_angle_cdeg = -6000;
        p.angle_increment_cdeg = 25;
        p.range_resolution_mm = 10;
        p.sound_velocity_flag = true;
        p.sound_velocity_header_mps = 1482.5;
        p.altitude_m = 12.5f;
        p.heave_m = 0.25f;
        p.ping_number = static_cast<std::uint32_t>(k);
        p.intensity_included = intensity;
        p.range_counts.resize(kMaxBeams);
        for (std::size_t i = 0; i < kMaxBeams; ++i) {
            p.range_counts[i] = static_cast<std::uint16_t>((i * 37 + k) % 4000);
        }
        if (intensity) p.intensities.assign(kMaxBeams, 500);
        EncodeRecord83P(p, {}, stream);
    }
    return stream;
}

// Frames and decodes the whole stream once; returns the number of pings decoded.
std::size_t FrameAndDecode(const std::vector<std::uint8_t>& stream,
                           StreamFramer& framer,
                           FloatOrderMemory& memory,
                           Ping83P& ping) {
    std::size_t pings = 0;
    for (std::size_t at = 0; at < stream.size(); at += kChunkBytes) {
        const std::size_t n = std::min(kChunkBytes, stream.size() - at);
        framer.Push(ByteSpan(stream.data() + at, n));
        while (true) {
            auto ev = framer.Next();
            if (std::holds_alternative<NeedMore>(ev)) break;
            if (const auto* r = std::get_if<Record>(&ev)) {
                const auto kind = DecodeRecord83PInto(r->bytes, memory, ping);
                pings += std::holds_alternative<RecordKind>(kind) ? 1 : 0;
            }
        }
    }
    return pings;
}

void BM_FrameAndDecode83P(benchmark::State& state) {
    const bool intensity = state.range(0) != 0;
    const std::vector<std::uint8_t> stream = MakeStream(intensity);
    StreamFramer framer;
    FloatOrderMemory memory;
    Ping83P ping;
    if (FrameAndDecode(stream, framer, memory, ping) != kRecordsPerStream) {
        state.SkipWithError("warm-up did not decode every record");
        return;
    }
    const std::uint64_t allocations_before = g_allocations.load();
    std::uint64_t records = 0;
    for (auto _ : state) {
        records += FrameAndDecode(stream, framer, memory, ping);
        benchmark::DoNotOptimize(ping.range_counts.data());
    }
    const std::uint64_t allocations = g_allocations.load() - allocations_before;
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * stream.size()));
    state.SetItemsProcessed(static_cast<std::int64_t>(records));
    state.counters["allocs_per_record"] =
        records == 0 ? 0.0 : static_cast<double>(allocations) / static_cast<double>(records);
    state.counters["record_bytes"] = static_cast<double>(stream.size() / kRecordsPerStream);
}
BENCHMARK(BM_FrameAndDecode83P)->ArgName("intensity")->Arg(0)->Arg(1);

void BM_FrameOnly83P(benchmark::State& state) {
    const bool intensity = state.range(0) != 0;
    const std::vector<std::uint8_t> stream = MakeStream(intensity);
    StreamFramer framer;
    for (auto _ : state) {
        for (std::size_t at = 0; at < stream.size(); at += kChunkBytes) {
            framer.Push(ByteSpan(stream.data() + at, std::min(kChunkBytes, stream.size() - at)));
            while (!std::holds_alternative<NeedMore>(framer.Next())) {
            }
        }
    }
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * stream.size()));
}
BENCHMARK(BM_FrameOnly83P)->ArgName("intensity")->Arg(0)->Arg(1);

void BM_Encode83P(benchmark::State& state) {
    const std::vector<std::uint8_t> stream = MakeStream(true);
    FloatOrderMemory memory;
    Ping83P ping;
    DecodeRecord83PInto(ByteSpan(stream.data(), kMaxRecordBytes), memory, ping);
    std::vector<std::uint8_t> out;
    out.reserve(kMaxRecordBytes);
    for (auto _ : state) {
        out.clear();
        EncodeRecord83P(ping, {}, out);
        benchmark::DoNotOptimize(out.data());
    }
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * kMaxRecordBytes));
}
BENCHMARK(BM_Encode83P);

}  // namespace

BENCHMARK_MAIN();
