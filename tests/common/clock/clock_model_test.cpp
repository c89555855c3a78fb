// SPDX-License-Identifier: MIT
// Clock models against synthetic truth: known offset and drift, random positive delays.
#include "common/clock/clock_model.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "common/gps_time.hpp"

namespace pitmap::clock {
namespace {

// 2024-03-01 in GPS microseconds (week 2303).
constexpr std::int64_t kGpsStart = 2303LL * kMicrosPerWeek + 100'000'000;

double Percentile(std::vector<double> v, double p) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const auto i = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size()))) - 1;
    return v[std::min(i, v.size() - 1)];
}

// A host clock that runs `drift_ppm` fast with an offset: host(gps).
struct HostTruth {
    std::int64_t offset_us = -GpsFromUnix(0, 18) + 1'234'567;  // Unix-ish, plus an error
    double drift_ppm = 40.0;
    std::int64_t Host(std::int64_t gps) const {
        return gps + offset_us +
               std::llround(drift_ppm * 1e-6 * static_cast<double>(gps - kGpsStart));
    }
    // Inverse, good to well below a microsecond.
    std::int64_t Gps(std::int64_t host) const {
        std::int64_t g = host - offset_us;
        for (int i = 0; i < 3; ++i) g -= Host(g) - host;
        return g;
    }
};

enum class DelayKind { kUniform20ms, kExponential5ms };

double Delay(std::mt19937_64& rng, DelayKind kind) {
    if (kind == DelayKind::kUniform20ms) return std::uniform_real_distribution<>(0, 20'000)(rng);
    return std::exponential_distribution<>(1.0 / 5'000)(rng);
}

// ------------------------------------------------------------------------------- envelope ----
TEST(LowerEnvelopeTest, ExactLineHasZeroResidual) {
    LowerEnvelope env({.bucket_us = 0});
    for (int i = 0; i <= 1000; ++i) {
        const std::int64_t x = 1'700'000'000'000'000 + i * 100'000LL;
        const double y = 5000.0 + 40e-6 * (i * 100'000.0);
        env.Add(x, std::llround(y));
    }
    ASSERT_TRUE(env.slope_fitted());
    EXPECT_NEAR(env.line().slope, 40e-6, 1e-8);
    EXPECT_NEAR(env.line().At(1'700'000'000'000'000), 5000.0, 1.0);  // extrapolated 40 s back
    EXPECT_LT(env.residual_rms(), 1.0);
}

TEST(LowerEnvelopeTest, LineStaysBelowEveryPointAndTouchesTheFloor) {
    std::mt19937_64 rng(1);
    LowerEnvelope env({.bucket_us = 0});
    std::vector<std::pair<std::int64_t, std::int64_t>> pts;
    for (int i = 0; i < 2000; ++i) {
        const std::int64_t x = i * 20'000LL;
        const std::int64_t y =
            std::llround(-300.0 + 1e-5 * x + Delay(rng, DelayKind::kUniform20ms));
        env.Add(x, y);
        pts.emplace_back(x, y);
    }
    for (const auto& [x, y] : pts) {
        if (x < env.first_x()) continue;
        EXPECT_LE(env.line().At(x), static_cast<double>(y) + 1e-6);
    }
    EXPECT_NEAR(env.line().At(20'000'000), -300.0 + 200.0, 100.0);
}

// ----------------------------------------------------------------------------- host model ----
struct HostRun {
    std::vector<double> errors_us;  // estimate - truth at every message arrival after warm-up
    HostClockModel model;
    explicit HostRun(const HostClockConfig& c = {}) : model(c) {}
};

// Messages at 50 Hz for `seconds`; errors collected after `warmup_s`.
void RunHost(HostRun& run,
             const HostTruth& truth,
             DelayKind kind,
             std::int64_t floor_us,
             int seconds,
             int warmup_s,
             std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    for (int i = 0; i < seconds * 50; ++i) {
        const std::int64_t gps = kGpsStart + i * 20'000LL;
        const std::int64_t rx = truth.Host(gps) + floor_us + std::llround(Delay(rng, kind));
        run.model.AddMessage(rx, gps, true);
        if (i >= warmup_s * 50) {
            const GpsEstimate e = run.model.ToGps(rx);
            EXPECT_NE(e.utime_gps, 0);
            run.errors_us.push_back(static_cast<double>(e.utime_gps - truth.Gps(rx)));
        }
    }
}

TEST(HostClockModelTest, NoSamplesMeansNoTime) {
    HostClockModel m;
    const GpsEstimate e = m.ToGps(1'700'000'000'000'000);
    EXPECT_EQ(e.utime_gps, 0);
    EXPECT_EQ(e.state, ClockState::kNoTime);
    EXPECT_EQ(m.Quality(1'700'000'000'000'000).state, ClockState::kNoTime);
    EXPECT_FALSE(m.AddPps(1'700'000'000'000'000));
}

TEST(HostClockModelTest, UniformDelaysOffsetAndDrift) {
    HostTruth truth;
    HostRun run;
    RunHost(run, truth, DelayKind::kUniform20ms, 0, 600, 20, 7);
    std::vector<double> abs_err;
    for (double e : run.errors_us) abs_err.push_back(std::abs(e));
    const double p99 = Percentile(abs_err, 0.99);
    const double p50 = Percentile(abs_err, 0.50);
    std::printf("host model, uniform 0-20 ms, 40 ppm: |error| p50 %.1f us, p99 %.1f us, max %.1f\n",
                p50,
                p99,
                Percentile(abs_err, 1.0));
    EXPECT_LT(p99, 500.0);
    const auto end = truth.Host(kGpsStart + 600'000'000);
    const ClockQuality q = run.model.Quality(end);
    EXPECT_EQ(q.state, ClockState::kLocked);
    // GPS runs slow against a fast host; the slope error is envelope noise / half the window.
    EXPECT_NEAR(q.drift_ppm, -40.0 / (1 + 40e-6), 3.0);
    EXPECT_GT(q.num_samples, 1000);
    EXPECT_EQ(q.resets, 0);
    EXPECT_GT(q.residual_rms_us, 5000.0);  // ~11.5 ms for uniform 0-20 ms
}

TEST(HostClockModelTest, ErrorStaysWithinTheDelayFloor) {
    HostTruth truth;
    const std::int64_t floor_us = 3000;
    HostRun run;
    RunHost(run, truth, DelayKind::kExponential5ms, floor_us, 300, 20, 11);
    const double lo = *std::min_element(run.errors_us.begin(), run.errors_us.end());
    const double hi = *std::max_element(run.errors_us.begin(), run.errors_us.end());
    std::printf("host model, floor 3 ms + exp(5 ms): error in [%.1f, %.1f] us\n", lo, hi);
    EXPECT_GE(lo, -floor_us - 500.0);
    EXPECT_LE(hi, 500.0);

    // The known floor configured as fixed latency removes the bias.
    HostRun fixed(HostClockConfig{.fixed_latency_us = floor_us});
    RunHost(fixed, truth, DelayKind::kExponential5ms, floor_us, 300, 20, 11);
    std::vector<double> abs_err;
    for (double e : fixed.errors_us) abs_err.push_back(std::abs(e));
    std::printf("host model, fixed latency configured: |error| p99 %.1f us\n",
                Percentile(abs_err, 0.99));
    EXPECT_LT(Percentile(abs_err, 0.99), 300.0);
}

TEST(HostClockModelTest, ConvergesThenLocks) {
    HostTruth truth;
    HostClockModel m;
    m.AddMessage(truth.Host(kGpsStart) + 5000, kGpsStart, true);
    EXPECT_EQ(m.ToGps(truth.Host(kGpsStart) + 5000).state, ClockState::kConverging);
    // One sample: the estimate is the receive time minus nothing, i.e. off by its delay.
    EXPECT_NEAR(
        static_cast<double>(m.ToGps(truth.Host(kGpsStart)).utime_gps - kGpsStart), -5000.0, 1.0);
    HostRun run;
    RunHost(run, truth, DelayKind::kUniform20ms, 0, 30, 0, 3);
    EXPECT_EQ(run.model.ToGps(truth.Host(kGpsStart + 30'000'000)).state, ClockState::kLocked);
}

TEST(HostClockModelTest, SingleLateMessageIsAnOutlierNotAJump) {
    HostTruth truth;
    HostRun run;
    RunHost(run, truth, DelayKind::kUniform20ms, 0, 60, 0, 5);
    const std::int64_t gps = kGpsStart + 60'000'000;
    run.model.AddMessage(truth.Host(gps) + 2'000'000, gps, true);  // 2 s late
    for (int i = 1; i < 50; ++i) {
        const std::int64_t g = gps + i * 20'000LL;
        run.model.AddMessage(truth.Host(g) + 1000, g, true);
    }
    const ClockQuality q = run.model.Quality(truth.Host(gps + 1'000'000));
    EXPECT_EQ(q.resets, 0);
    EXPECT_EQ(q.outliers, 1);
    EXPECT_EQ(q.state, ClockState::kLocked);
}

TEST(HostClockModelTest, HostClockStepResetsTheModel) {
    HostTruth truth;
    HostRun run;
    RunHost(run, truth, DelayKind::kUniform20ms, 0, 60, 0, 21);
    // The host clock steps back by 2 s (an NTP step): x goes backwards.
    HostTruth stepped = truth;
    stepped.offset_us -= 2'000'000;
    std::mt19937_64 rng(22);
    std::vector<double> late_errors;
    for (int i = 0; i < 60 * 50; ++i) {
        const std::int64_t gps = kGpsStart + 60'000'000 + i * 20'000LL;
        const std::int64_t rx =
            stepped.Host(gps) + std::llround(Delay(rng, DelayKind::kUniform20ms));
        run.model.AddMessage(rx, gps, true);
        if (i > 30 * 50)
            late_errors.push_back(
                std::abs(static_cast<double>(run.model.ToGps(rx).utime_gps - stepped.Gps(rx))));
    }
    const ClockQuality q = run.model.Quality(stepped.Host(kGpsStart + 120'000'000));
    EXPECT_EQ(q.resets, 1);
    EXPECT_EQ(q.state, ClockState::kLocked);
    EXPECT_LT(Percentile(late_errors, 0.99), 1000.0);
}

TEST(HostClockModelTest, ReceiverResetWeekZeroGivesNoTime) {
    HostTruth truth;
    HostRun run;
    RunHost(run, truth, DelayKind::kUniform20ms, 0, 30, 0, 4);
    const std::int64_t h = truth.Host(kGpsStart + 30'000'000);
    EXPECT_NE(run.model.ToGps(h).utime_gps, 0);
    // After a reset the receiver reports week 0 and the time since power-up.
    run.model.AddMessage(h, GpsUtimeFromWeekMs(0, 4'005'000), true);
    EXPECT_EQ(run.model.receiver_resets(), 1);
    EXPECT_EQ(run.model.ToGps(h).utime_gps, 0);
    EXPECT_EQ(run.model.ToGps(h).state, ClockState::kNoTime);
    const ClockQuality q = run.model.Quality(h);
    EXPECT_EQ(q.state, ClockState::kNoTime);
    EXPECT_EQ(q.resets, 1);
    // Time status below FINE says the same without week 0.
    run.model.AddMessage(h + 20'000, kGpsStart + 30'020'000, false);
    EXPECT_EQ(run.model.ToGps(h + 20'000).utime_gps, 0);
    // Valid time again: the model comes back.
    for (int i = 0; i < 100; ++i) {
        const std::int64_t gps = kGpsStart + 40'000'000 + i * 20'000LL;
        run.model.AddMessage(truth.Host(gps) + 100, gps, true);
    }
    const std::int64_t h2 = truth.Host(kGpsStart + 42'000'000);
    EXPECT_NEAR(static_cast<double>(run.model.ToGps(h2).utime_gps - truth.Gps(h2)), 0.0, 500.0);
}

TEST(HostClockModelTest, HoldoverThenNoTime) {
    HostTruth truth;
    HostRun run;
    RunHost(run, truth, DelayKind::kUniform20ms, 0, 120, 0, 9);
    const std::int64_t last_gps = kGpsStart + 120'000'000;
    const std::int64_t h10 = truth.Host(last_gps + 10'000'000);
    const GpsEstimate e10 = run.model.ToGps(h10);
    EXPECT_EQ(e10.state, ClockState::kHoldover);
    EXPECT_NEAR(static_cast<double>(e10.utime_gps - truth.Gps(h10)), 0.0, 1000.0);
    EXPECT_GT(e10.stddev_us, run.model.ToGps(truth.Host(last_gps)).stddev_us);
    const std::int64_t h400 = truth.Host(last_gps + 400'000'000);
    EXPECT_EQ(run.model.ToGps(h400).state, ClockState::kNoTime);
    EXPECT_EQ(run.model.ToGps(h400).utime_gps, 0);
}

TEST(HostClockModelTest, PpsTakesOverAndIsMoreAccurate) {
    HostTruth truth;
    HostRun run;
    RunHost(run, truth, DelayKind::kUniform20ms, 0, 30, 0, 13);
    std::mt19937_64 rng(14);
    std::vector<double> errs;
    for (int s = 31; s < 90; ++s) {
        const std::int64_t pulse = kGpsStart + s * 1'000'000LL;
        // Interrupt latency 2..12 us.
        ASSERT_TRUE(run.model.AddPps(truth.Host(pulse) +
                                     std::llround(std::uniform_real_distribution<>(2, 12)(rng))));
        for (int k = 0; k < 50; ++k) {
            const std::int64_t gps = pulse + k * 20'000LL;
            const std::int64_t rx =
                truth.Host(gps) + std::llround(Delay(rng, DelayKind::kUniform20ms));
            run.model.AddMessage(rx, gps, true);
            if (s > 35)
                errs.push_back(
                    std::abs(static_cast<double>(run.model.ToGps(rx).utime_gps - truth.Gps(rx))));
        }
    }
    const double p99 = Percentile(errs, 0.99);
    std::printf("host model with PPS: |error| p99 %.1f us\n", p99);
    EXPECT_LT(p99, 30.0);
    const ClockQuality q = run.model.Quality(truth.Host(kGpsStart + 89'500'000));
    EXPECT_TRUE(q.from_pps);
    EXPECT_NEAR(q.drift_ppm, -40.0, 1.0);
    // No pulse for longer than pps_timeout_us: back to the message envelope.
    EXPECT_FALSE(run.model.Quality(truth.Host(kGpsStart + 93'000'000)).from_pps);
}

TEST(HostClockModelTest, ConfigValidation) {
    EXPECT_TRUE(HostClockConfig{}.Validate().empty());
    EXPECT_TRUE(SonarClockConfig{}.Validate().empty());
    HostClockConfig bad;
    bad.model.max_delay_us = 0;
    bad.model.holdover_after_us = -1;
    bad.pps_min_samples = 1;
    EXPECT_EQ(bad.Validate().size(), 3u);
}

// ---------------------------------------------------------------------------- sonar model ----
// The topside clock: offset 3.2 s, 40 ppm fast, stamps truncated to milliseconds (83P v1.10).
struct TopsideTruth {
    std::int64_t offset_us = -GpsFromUnix(0, 18) + 3'200'000;
    double drift_ppm = 40.0;
    std::int64_t HeaderExact(std::int64_t gps) const {
        return gps + offset_us +
               std::llround(drift_ppm * 1e-6 * static_cast<double>(gps - kGpsStart));
    }
    std::int64_t Header(std::int64_t gps) const {
        const std::int64_t h = HeaderExact(gps);
        return h - h % 1000;
    }
};

struct SonarRun {
    std::vector<double> abs_errors_us;
    SonarClockModel model;
    std::int64_t model_stamps = 0;
};

// Pings at 10 Hz (with a little jitter in the ping instants), age at send 30 ms, random
// network delay.
void RunSonar(SonarRun& run,
              const TopsideTruth& truth,
              DelayKind kind,
              int seconds,
              std::int64_t t0,
              std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    for (int i = 0; i < seconds * 10; ++i) {
        const std::int64_t gps =
            t0 + i * 100'000LL + std::uniform_int_distribution<std::int64_t>(0, 999)(rng);
        const std::int64_t age = 30'000;
        SonarPingTimes t;
        t.utime_header = truth.Header(gps);
        t.age_at_send_us = age;
        t.utime_gps_receive = gps + age + std::llround(Delay(rng, kind));
        const SonarStamp s = run.model.Update(t);
        ASSERT_NE(s.utime_gps, 0);
        if (s.method == SonarStampMethod::kHeaderModel) ++run.model_stamps;
        run.abs_errors_us.push_back(std::abs(static_cast<double>(s.utime_gps - gps)));
    }
}

TEST(SonarClockModelTest, HeaderClockAccuracy) {
    for (DelayKind kind : {DelayKind::kUniform20ms, DelayKind::kExponential5ms}) {
        TopsideTruth truth;
        SonarRun run;
        RunSonar(run, truth, kind, 600, kGpsStart, 17);
        const double p99 = Percentile(run.abs_errors_us, 0.99);
        const std::vector<double> after(run.abs_errors_us.begin() + 300, run.abs_errors_us.end());
        std::printf(
            "sonar model, %s, 40 ppm, ms header: |error| p50 %.1f us, p99 %.1f us (all pings); "
            "p99 %.1f us, max %.1f us after 30 s\n",
            kind == DelayKind::kUniform20ms ? "uniform 0-20 ms" : "exponential 5 ms",
            Percentile(run.abs_errors_us, 0.5),
            p99,
            Percentile(after, 0.99),
            Percentile(after, 1.0));
        EXPECT_LT(p99, 2000.0);
        EXPECT_LT(Percentile(after, 0.99), 1000.0);
        const ClockQuality q = run.model.Quality(truth.Header(kGpsStart + 600'000'000));
        EXPECT_EQ(q.state, ClockState::kLocked);
        EXPECT_NEAR(q.drift_ppm, -40.0, 8.0);  // GPS - header shrinks at 40 ppm; 10 Hz, ms ticks
        EXPECT_EQ(q.resets, 0);
    }
}

TEST(SonarClockModelTest, MissingHeaderClockFallsBackToReceiveTime) {
    SonarClockModel m;
    const SonarStamp s = m.Update(
        {.utime_header = 0, .utime_gps_receive = kGpsStart + 50'000, .age_at_send_us = 30'000});
    EXPECT_EQ(s.method, SonarStampMethod::kReceiveTime);
    EXPECT_EQ(s.utime_gps, kGpsStart + 20'000);
    EXPECT_EQ(m.fallbacks(), 1);
}

TEST(SonarClockModelTest, NothingKnownMeansNoTime) {
    SonarClockModel m;
    const SonarStamp s = m.Update({.utime_header = 1'700'000'000'000'000});
    EXPECT_EQ(s.method, SonarStampMethod::kNone);
    EXPECT_EQ(s.utime_gps, 0);
    EXPECT_EQ(m.ToGps(1'700'000'000'000'000).utime_gps, 0);
}

TEST(SonarClockModelTest, HeaderJumpUsesFallbackThenRelearns) {
    TopsideTruth truth;
    SonarRun run;
    RunSonar(run, truth, DelayKind::kUniform20ms, 120, kGpsStart, 31);
    TopsideTruth jumped = truth;
    jumped.offset_us += 2'000'000;  // someone set the topside PC clock
    std::mt19937_64 rng(32);
    std::vector<double> errs;
    int fallbacks = 0;
    for (int i = 0; i < 600; ++i) {
        const std::int64_t gps = kGpsStart + 120'000'000 + i * 100'000LL;
        SonarPingTimes t{
            jumped.Header(gps), gps + std::llround(Delay(rng, DelayKind::kUniform20ms)), 0};
        const SonarStamp s = run.model.Update(t);
        if (s.method == SonarStampMethod::kReceiveTime) ++fallbacks;
        errs.push_back(std::abs(static_cast<double>(s.utime_gps - gps)));
    }
    EXPECT_EQ(run.model.Quality(jumped.Header(kGpsStart + 180'000'000)).resets, 1);
    EXPECT_EQ(fallbacks, 4);  // jump_confirm_samples - 1 pings wait for the confirmation
    EXPECT_LE(*std::max_element(errs.begin(), errs.end()), 21'000.0);  // never worse than the
                                                                       // fallback's delay
    const std::vector<double> late(errs.begin() + 300, errs.end());
    EXPECT_LT(Percentile(late, 0.99), 1000.0);
}

TEST(SonarClockModelTest, HoldoverWithoutReceiveTimes) {
    TopsideTruth truth;
    SonarRun run;
    RunSonar(run, truth, DelayKind::kUniform20ms, 120, kGpsStart, 41);
    // The host model lost GPS time: records keep coming, the header model carries on.
    const std::int64_t gps = kGpsStart + 125'000'000;
    const SonarStamp s = run.model.Update({.utime_header = truth.Header(gps)});
    EXPECT_EQ(s.method, SonarStampMethod::kHeaderModel);
    EXPECT_EQ(s.state, ClockState::kHoldover);
    EXPECT_NEAR(static_cast<double>(s.utime_gps - gps), 0.0, 1500.0);
}

}  // namespace
}  // namespace pitmap::clock
