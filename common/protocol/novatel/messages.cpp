// SPDX-License-Identifier: MIT
#include "common/protocol/novatel/messages.hpp"

#include <cmath>

#include "common/gps_time.hpp"

namespace pitmap::protocol::novatel {
namespace {

template <typename E>
struct EnumName {
    E value;
    std::string_view name;
};

template <typename E, std::size_t N>
std::string_view Lookup(const std::array<EnumName<E>, N>& table, E v) {
    for (const auto& e : table) {
        if (e.value == v) return e.name;
    }
    return {};
}

using TS = TimeStatus;
constexpr std::array<EnumName<TS>, 13> kTimeStatusNames = {{
    {TS::kUnknown, "UNKNOWN"},
    {TS::kApproximate, "APPROXIMATE"},
    {TS::kCoarseAdjusting, "COARSEADJUSTING"},
    {TS::kCoarse, "COARSE"},
    {TS::kCoarseSteering, "COARSESTEERING"},
    {TS::kFreewheeling, "FREEWHEELING"},
    {TS::kFineAdjusting, "FINEADJUSTING"},
    {TS::kFine, "FINE"},
    {TS::kFineBackupSteering, "FINEBACKUPSTEERING"},
    {TS::kFineSteering, "FINESTEERING"},
    {TS::kSatTime, "SATTIME"},
    {TS::kExtern, "EXTERN"},
    {TS::kExact, "EXACT"},
}};

using SS = SolutionStatus;
constexpr std::array<EnumName<SS>, 21> kSolutionStatusNames = {{
    {SS::kSolComputed, "SOL_COMPUTED"},
    {SS::kInsufficientObs, "INSUFFICIENT_OBS"},
    {SS::kNoConvergence, "NO_CONVERGENCE"},
    {SS::kSingularity, "SINGULARITY"},
    {SS::kCovTrace, "COV_TRACE"},
    {SS::kTestDist, "TEST_DIST"},
    {SS::kColdStart, "COLD_START"},
    {SS::kVHLimit, "V_H_LIMIT"},
    {SS::kVariance, "VARIANCE"},
    {SS::kResiduals, "RESIDUALS"},
    {SS::kDeltaPos, "DELTA_POS"},
    {SS::kNegativeVar, "NEGATIVE_VAR"},
    {SS::kIntegrityWarning, "INTEGRITY_WARNING"},
    {SS::kInsInactive, "INS_INACTIVE"},
    {SS::kInsAligning, "INS_ALIGNING"},
    {SS::kInsBad, "INS_BAD"},
    {SS::kImuUnplugged, "IMU_UNPLUGGED"},
    {SS::kPending, "PENDING"},
    {SS::kInvalidFix, "INVALID_FIX"},
    {SS::kUnauthorized, "UNAUTHORIZED"},
    {SS::kInvalidRate, "INVALID_RATE"},
}};

using PT = PositionType;
constexpr std::array<EnumName<PT>, 31> kPositionTypeNames = {{
    {PT::kNone, "NONE"},
    {PT::kFixedPos, "FIXEDPOS"},
    {PT::kFixedHeight, "FIXEDHEIGHT"},
    {PT::kDopplerVelocity, "DOPPLER_VELOCITY"},
    {PT::kSingle, "SINGLE"},
    {PT::kPsrDiff, "PSRDIFF"},
    {PT::kWaas, "WAAS"},
    {PT::kPropagated, "PROPAGATED"},
    {PT::kL1Float, "L1_FLOAT"},
    {PT::kIonoFreeFloat, "IONOFREE_FLOAT"},
    {PT::kNarrowFloat, "NARROW_FLOAT"},
    {PT::kL1Int, "L1_INT"},
    {PT::kWideInt, "WIDE_INT"},
    {PT::kNarrowInt, "NARROW_INT"},
    {PT::kRtkDirectIns, "RTK_DIRECT_INS"},
    {PT::kInsSbas, "INS_SBAS"},
    {PT::kInsPsrSp, "INS_PSRSP"},
    {PT::kInsPsrDiff, "INS_PSRDIFF"},
    {PT::kInsRtkFloat, "INS_RTKFLOAT"},
    {PT::kInsRtkFixed, "INS_RTKFIXED"},
    {PT::kPppConverging, "PPP_CONVERGING"},
    {PT::kPpp, "PPP"},
    {PT::kOperational, "OPERATIONAL"},
    {PT::kWarning, "WARNING"},
    {PT::kOutOfBounds, "OUT_OF_BOUNDS"},
    {PT::kInsPppConverging, "INS_PPP_CONVERGING"},
    {PT::kInsPpp, "INS_PPP"},
    {PT::kPppBasicConverging, "PPP_BASIC_CONVERGING"},
    {PT::kPppBasic, "PPP_BASIC"},
    {PT::kInsPppBasicConverging, "INS_PPP_BASIC_CONVERGING"},
    {PT::kInsPppBasic, "INS_PPP_BASIC"},
}};

using IS = InsStatus;
constexpr std::array<EnumName<IS>, 11> kInsStatusNames = {{
    {IS::kInactive, "INS_INACTIVE"},
    {IS::kAligning, "INS_ALIGNING"},
    {IS::kHighVariance, "INS_HIGH_VARIANCE"},
    {IS::kSolutionGood, "INS_SOLUTION_GOOD"},
    {IS::kSolutionFree, "INS_SOLUTION_FREE"},
    {IS::kAlignmentComplete, "INS_ALIGNMENT_COMPLETE"},
    {IS::kDeterminingOrientation, "DETERMINING_ORIENTATION"},
    {IS::kWaitingInitialPos, "WAITING_INITIALPOS"},
    {IS::kWaitingAzimuth, "WAITING_AZIMUTH"},
    {IS::kInitializingBiases, "INITIALIZING_BIASES"},
    {IS::kMotionDetect, "MOTION_DETECT"},
}};

constexpr std::array<EnumName<ClockModelStatus>, 4> kClockNames = {{
    {ClockModelStatus::kValid, "VALID"},
    {ClockModelStatus::kConverging, "CONVERGING"},
    {ClockModelStatus::kIterating, "ITERATING"},
    {ClockModelStatus::kInvalid, "INVALID"},
}};

constexpr std::array<EnumName<UtcStatus>, 3> kUtcNames = {{
    {UtcStatus::kInvalid, "INVALID"},
    {UtcStatus::kValid, "VALID"},
    {UtcStatus::kWarning, "WARNING"},
}};

std::int64_t BodyTime(std::uint32_t week, double seconds) {
    if (week == 0 || !std::isfinite(seconds) || seconds < 0.0 || seconds > 2.0 * kSecondsPerWeek) {
        return 0;
    }
    return GpsUtimeFromWeekTow(static_cast<int>(week), seconds);
}

constexpr double kFeetToMetres = 0.3048;
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr double kArcsecToRad = kDegToRad / 3600.0;
constexpr double kStandardGravity = 9.80665;

}  // namespace

std::string_view ToString(TimeStatus v) {
    return Lookup(kTimeStatusNames, v);
}
std::string_view ToString(SolutionStatus v) {
    return Lookup(kSolutionStatusNames, v);
}
std::string_view ToString(PositionType v) {
    return Lookup(kPositionTypeNames, v);
}
std::string_view ToString(InsStatus v) {
    return Lookup(kInsStatusNames, v);
}
std::string_view ToString(ClockModelStatus v) {
    return Lookup(kClockNames, v);
}
std::string_view ToString(UtcStatus v) {
    return Lookup(kUtcNames, v);
}

std::string_view DatumName(std::uint32_t datum_id) {
    if (datum_id == 61) return "WGS84";
    if (datum_id == 63) return "USER";
    return {};
}

std::string_view ToString(DecodeErrorKind kind) {
    switch (kind) {
        case DecodeErrorKind::kRunt:
            return "runt";
        case DecodeErrorKind::kBadHeader:
            return "bad_header";
        case DecodeErrorKind::kBadField:
            return "bad_field";
        case DecodeErrorKind::kCount:
            break;
    }
    return "unknown";
}

std::int64_t Header::utime_gps() const {
    if (gps_week == 0) return 0;
    if (kind == HeaderKind::kLongBinary || kind == HeaderKind::kAscii) {
        if (time_status == TimeStatus::kUnknown) return 0;
    }
    return GpsUtimeFromWeekMs(gps_week, gps_ms);
}

std::int64_t BestVel::utime_gps() const {
    const std::int64_t t = header.utime_gps();
    if (t == 0 || !std::isfinite(latency_s) || std::fabs(latency_s) > 1e6f) return t;
    return t - static_cast<std::int64_t>(std::llround(static_cast<double>(latency_s) * 1e6));
}

std::int64_t InsPva::utime_gps() const {
    return BodyTime(gps_week, gps_seconds);
}
std::int64_t InsAtt::utime_gps() const {
    return BodyTime(gps_week, gps_seconds);
}
std::int64_t CorrImuData::utime_gps() const {
    return BodyTime(gps_week, gps_seconds);
}
std::int64_t RawImu::utime_gps() const {
    return BodyTime(gps_week, gps_seconds);
}
std::int64_t MarkTime::utime_gps() const {
    return gps_week <= 0 ? 0 : BodyTime(static_cast<std::uint32_t>(gps_week), gps_seconds);
}

bool Response::ok() const {
    if (form == Form::kBinary) return response_id == 1;
    return text == "OK";
}

std::optional<ImuScale> ImuScaleFor(std::int32_t imu_type, double imu_rate_hz) {
    const auto rate_or = [imu_rate_hz](double nominal) {
        return imu_rate_hz > 0.0 ? imu_rate_hz : nominal;
    };
    ImuScale s;
    switch (imu_type) {
        case 1:
        case 5:
        case 11:
        case 20:
        case 27:
        case 28:
            s = {std::ldexp(1.0, -33), std::ldexp(1.0, -27) * kFeetToMetres, 100.0};
            break;
        case 4:
        case 12:
            s = {std::ldexp(1.0, -33), std::ldexp(1.0, -26) * kFeetToMetres, 100.0};
            break;
        case 8:
            s = {std::ldexp(1.0, -19), std::ldexp(1.0, -14), 200.0};
            break;
        case 26:
        case 52:
            s = {1.0e-9, 2.0e-8, 200.0};
            break;
        case 13:
            s = {0.1 * std::ldexp(1.0, -8) * kArcsecToRad, 0.05 * std::ldexp(1.0, -15), 200.0};
            break;
        case 16:
        case 33:
            // §6.9 note: unit unverified; NovAtel's driver applies the number as rad/count.
            s = {0.1 / (3600.0 * 256.0),
                 0.05 * std::ldexp(1.0, -15),
                 imu_type == 33 ? 200.0 : 100.0};
            break;
        case 31:
            s = {720.0 / std::ldexp(1.0, 31) * kDegToRad, 200.0 / std::ldexp(1.0, 31), 200.0};
            break;
        case 32:
        case 56:
            s = {std::ldexp(1.0, -21) * kDegToRad, std::ldexp(1.0, -22), 125.0};
            break;
        case 58:
        case 68:
        case 69: {
            const double nominal = imu_type == 58 ? 200.0 : (imu_type == 68 ? 100.0 : 400.0);
            s = {std::ldexp(1.0, -33), std::ldexp(1.0, -29), nominal};
            break;
        }
        case 41:
        case 62: {
            const double nominal = imu_type == 41 ? 125.0 : 200.0;
            const double rate = rate_or(nominal);
            s = {(0.008 / 65536.0) / rate * kDegToRad,
                 (0.2 / 65536.0) * (kStandardGravity / 1000.0) / rate,
                 nominal};
            break;
        }
        case 61: {
            const double rate = rate_or(200.0);
            s = {(0.0151515 / 65536.0) / rate * kDegToRad,
                 (0.4 / 65536.0) * (kStandardGravity / 1000.0) / rate,
                 200.0};
            break;
        }
        default:
            return std::nullopt;
    }
    return s;
}

ImuIncrements ScaleRawImu(const RawImu& raw, const ImuScale& scale, double imu_rate_hz) {
    ImuIncrements out;
    for (std::size_t i = 0; i < 3; ++i) {
        out.delta_angle_rad[i] = static_cast<double>(raw.gyro_counts[i]) * scale.gyro_rad_per_count;
        out.delta_velocity_mps[i] =
            static_cast<double>(raw.accel_counts[i]) * scale.accel_mps_per_count;
        out.angular_rate_radps[i] = out.delta_angle_rad[i] * imu_rate_hz;
        out.acceleration_mps2[i] = out.delta_velocity_mps[i] * imu_rate_hz;
    }
    return out;
}

}  // namespace pitmap::protocol::novatel
