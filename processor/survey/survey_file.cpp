// SPDX-License-Identifier: MIT
#include "processor/survey/survey_file.hpp"

#include <sys/stat.h>

#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/formats/replace_file.hpp"
#include "common/protocol/novatel/crc32.hpp"
#include "processor/survey/survey_records.hpp"

namespace pitmap::proc::survey {

namespace {

using nlohmann::json;
namespace fs = std::filesystem;

constexpr char kMagic[8] = {'P', 'M', 'S', 'U', 'R', 'V', 'E', 'Y'};
constexpr std::uint32_t kByteOrder = std::endian::native == std::endian::little ? 1u : 2u;
constexpr std::size_t kTagBytes = 16;
constexpr std::size_t kHeadBytes = sizeof(kMagic) + 3 * 4;
constexpr std::size_t kSectionHeadBytes = kTagBytes + 8 + 4;
constexpr const char* kTrajectoryTags[kNumTrajectoryVersions] = {
    "traj.ins", "traj.calibrated", "traj.slam"};

struct DiskPose {
    double v[7];  // x, y, z, qw, qx, qy, qz
    std::uint32_t valid;
    std::uint32_t zero;
};

// A section payload being built in memory.
class Payload {
public:
    void Bytes(const void* p, std::size_t n) {
        // resize + memcpy: gcc 12's -Wstringop-overflow misreads vector::insert into an empty
        // vector once SaveSurvey inlines the intensity section's payload.
        if (n == 0) return;
        const std::size_t at = bytes_.size();
        bytes_.resize(at + n);
        std::memcpy(bytes_.data() + at, p, n);
    }
    template <typename T>
    void Value(const T& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        Bytes(&v, sizeof v);
    }
    template <typename T>
    void Vec(const std::vector<T>& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        Value(static_cast<std::uint64_t>(v.size()));
        Value(static_cast<std::uint64_t>(sizeof(T)));
        Bytes(v.data(), v.size() * sizeof(T));
    }
    // u64 count, u64 record bytes, then each record as write(ByteWriter&, record) lays it.
    template <typename T, typename Write>
    void Records(const std::vector<T>& v, std::size_t record_bytes, Write write) {
        Value(static_cast<std::uint64_t>(v.size()));
        Value(static_cast<std::uint64_t>(record_bytes));
        bytes_.reserve(bytes_.size() + v.size() * record_bytes);
        ByteWriter w(bytes_);
        for (const T& x : v) write(w, x);
    }
    const std::vector<std::uint8_t>& bytes() const { return bytes_; }

private:
    std::vector<std::uint8_t> bytes_;
};

// Reads a section payload held in memory; the first problem is kept in `error`.
class Cursor {
public:
    Cursor(const std::vector<std::uint8_t>& b, std::string section)
        : b_(b), section_(std::move(section)) {}
    bool Bytes(void* p, std::size_t n, const char* what) {
        if (!error.empty()) return false;
        if (n > b_.size() - pos_) return Fail(std::string("truncated in ") + what);
        if (n > 0) std::memcpy(p, b_.data() + pos_, n);
        pos_ += n;
        return true;
    }
    template <typename T>
    bool Value(T& v, const char* what) {
        return Bytes(&v, sizeof v, what);
    }
    template <typename T>
    bool Vec(std::vector<T>& v, const char* what) {
        static_assert(std::is_trivially_copyable_v<T>);
        std::uint64_t n = 0, sz = 0;
        if (!Value(n, what) || !Value(sz, what)) return false;
        if (sz != sizeof(T)) {
            return Fail(std::string(what) + ": element size " + std::to_string(sz) + ", expected " +
                        std::to_string(sizeof(T)));
        }
        const std::size_t left = b_.size() - pos_;
        if (n > left / sizeof(T)) {
            return Fail(std::string(what) + ": count " + std::to_string(n) + " needs " +
                        std::to_string(n) + " x " + std::to_string(sizeof(T)) + " bytes but only " +
                        std::to_string(left) + " remain");
        }
        v.resize(n);
        return Bytes(v.data(), n * sizeof(T), what);
    }
    // Records as Payload::Records wrote them, each read by read(ByteReader&) from exactly
    // record_bytes.
    template <typename T, typename Read>
    bool Records(std::vector<T>& v, std::size_t record_bytes, Read read, const char* what) {
        std::uint64_t n = 0, sz = 0;
        if (!Value(n, what) || !Value(sz, what)) return false;
        if (sz != record_bytes) {
            return Fail(std::string(what) + ": record size " + std::to_string(sz) + ", expected " +
                        std::to_string(record_bytes));
        }
        const std::size_t left = b_.size() - pos_;
        if (n > left / record_bytes) {
            return Fail(std::string(what) + ": count " + std::to_string(n) + " needs " +
                        std::to_string(n) + " x " + std::to_string(record_bytes) +
                        " bytes but only " + std::to_string(left) + " remain");
        }
        v.resize(n);
        for (std::size_t i = 0; i < n; ++i) {
            ByteReader r(b_.data() + pos_, record_bytes);
            v[i] = read(r);
            pos_ += record_bytes;
        }
        return true;
    }
    bool Finish() {
        if (!error.empty()) return false;
        if (pos_ != b_.size()) {
            return Fail(std::to_string(b_.size() - pos_) + " unexpected bytes at the end");
        }
        return true;
    }
    bool Fail(const std::string& message) {
        if (error.empty()) error = "section " + section_ + ": " + message;
        return false;
    }
    std::string error;

private:
    const std::vector<std::uint8_t>& b_;
    std::string section_;
    std::size_t pos_ = 0;
};

std::uint32_t Crc(const std::vector<std::uint8_t>& b) {
    return protocol::novatel::Crc32({b.data(), b.size()});
}

// ---- state ----

json StateJson(const SurveyModel& m) {
    const SonarClockState& c = m.clock;
    json refraction = nullptr;
    if (m.refraction.enabled()) {
        refraction = {{"svp_files", m.refraction.svp_files},
                      {"selection", svp::ToString(m.refraction.selection)},
                      {"surface_speed", svp::ToString(m.refraction.surface_speed)},
                      {"ins_height_above_waterline_m", m.refraction.ins_height_above_waterline_m}};
    }
    json state = {{"vehicle_yaml", m.vehicle_yaml},
                  {"nominal_mount", MountJson(m.nominal_mount)},
                  {"mount", MountJson(m.mount)},
                  {"world_origin", OriginJson(m.origin)},
                  {"sonar_clock", ClockJson(c)},
                  {"refraction", refraction},
                  {"calibration", ToString(m.calibration)}};
    // Optional (surveys written before run ids have none): no format version change.
    if (!m.run_id.empty()) state["run_id"] = m.run_id;
    // Optional likewise (only a calibrated survey has one; older files have none).
    if (std::isfinite(m.boresight_sd_deg[0]))
        state["boresight_sd_deg"] = {
            m.boresight_sd_deg[0], m.boresight_sd_deg[1], m.boresight_sd_deg[2]};
    return state;
}

// The state section into `m`; an error says which key is wrong.
Status StateFromJson(const json& j, SurveyModel& m) {
    try {
        m.vehicle_yaml = j.at("vehicle_yaml").get<std::string>();
        m.run_id.clear();
        if (const auto id = j.find("run_id"); id != j.end()) {
            m.run_id = id->get<std::string>();
            if (!IsRunId(m.run_id)) return Error{"run_id: not 32 lower-case hex digits"};
        }
        auto nominal = MountFromJson(j.at("nominal_mount"));
        if (!nominal) return Error{"nominal_mount: " + nominal.error().message};
        m.nominal_mount = *nominal;
        auto mount = MountFromJson(j.at("mount"));
        if (!mount) return Error{"mount: " + mount.error().message};
        m.mount = *mount;
        m.boresight_sd_deg = kNoBoresightSd;
        if (const auto sd = j.find("boresight_sd_deg"); sd != j.end()) {
            const auto v = sd->get<std::vector<double>>();
            if (v.size() != 3 || !std::isfinite(v[0]) || !std::isfinite(v[1]) ||
                !std::isfinite(v[2]) || v[0] < 0 || v[1] < 0 || v[2] < 0)
                return Error{"boresight_sd_deg: not three finite sigmas"};
            m.boresight_sd_deg = {v[0], v[1], v[2]};
        }
        auto origin = OriginFromJson(j.at("world_origin"));
        if (!origin) return Error{"world_origin: " + origin.error().message};
        if (!std::isfinite(origin->latitude_deg) || std::abs(origin->latitude_deg) > 90 ||
            !std::isfinite(origin->longitude_deg) || !std::isfinite(origin->height_m)) {
            return Error{"world_origin: not a position on the Earth"};
        }
        m.origin = *origin;
        const json& c = j.at("sonar_clock");
        m.clock.configured = c.at("configured").get<bool>();
        m.clock.configured_offset_s = c.at("configured_offset_s").get<double>();
        m.clock.coarse_correction_s = c.at("coarse_correction_s").get<double>();
        m.clock.coarse_sigma_s = c.at("coarse_sigma_s").get<double>();
        m.clock.latency_applied = c.at("latency_applied").get<bool>();
        m.clock.latency_s = c.at("latency_s").get<double>();
        m.clock.latency_formal_sd_s = c.at("latency_formal_sd_s").get<double>();
        // Surveys written before the clock rate was estimated have none.
        m.clock.rate_ppm = c.value("rate_ppm", 0.0);
        m.clock.rate_sigma_ppm = c.value("rate_sigma_ppm", 0.0);
        m.clock.rate_reference_utime = c.value("rate_reference_utime", std::int64_t{0});
        for (double v : {m.clock.configured_offset_s,
                         m.clock.coarse_correction_s,
                         m.clock.coarse_sigma_s,
                         m.clock.latency_s,
                         m.clock.latency_formal_sd_s,
                         m.clock.rate_ppm,
                         m.clock.rate_sigma_ppm}) {
            if (!std::isfinite(v)) return Error{"sonar_clock: not a finite number"};
        }
        m.refraction = {};
        if (const json& r = j.at("refraction"); !r.is_null()) {
            m.refraction.svp_files = r.at("svp_files").get<std::vector<std::string>>();
            if (!svp::ParseCastSelection(r.at("selection").get<std::string>(),
                                         m.refraction.selection)) {
                return Error{"refraction.selection: not a known cast selection"};
            }
            if (!svp::ParseSurfaceSpeedSource(r.at("surface_speed").get<std::string>(),
                                              m.refraction.surface_speed)) {
                return Error{"refraction.surface_speed: not profile or header"};
            }
            m.refraction.ins_height_above_waterline_m =
                r.at("ins_height_above_waterline_m").get<double>();
        }
        const std::string cal = j.at("calibration").get<std::string>();
        bool known = false;
        for (auto s : {CalibrationState::kNotRun,
                       CalibrationState::kCalibrated,
                       CalibrationState::kKeptNominal,
                       CalibrationState::kNoOverlap}) {
            if (cal == ToString(s)) {
                m.calibration = s;
                known = true;
            }
        }
        if (!known) return Error{"calibration: unknown state \"" + cal + "\""};
    } catch (const std::exception& e) {
        return Error{e.what()};
    }
    return Ok{};
}

// ---- ingest ----

Payload IngestPayload(const IngestedSeries& r) {
    Payload p;
    p.Value(static_cast<std::int32_t>(r.nav.leap_seconds));
    p.Value(static_cast<std::uint32_t>(r.pings.clock));
    p.Records(r.nav.samples, records::kNavBytes, records::WriteNav);
    p.Records(r.nav.stddevs, records::kStdDevBytes, records::WriteStdDev);
    p.Records(r.pings.pings, records::kPingBytes, records::WritePing);
    p.Vec(r.pings.range_counts);
    return p;
}

// `format`: the file's; formats 1-4 held the ping records in their old layout.
Status IngestFromPayload(const std::vector<std::uint8_t>& bytes,
                         std::uint32_t format,
                         IngestedSeries& r) {
    Cursor in(bytes, "ingest");
    std::int32_t leap = -1;
    std::uint32_t clock = 0;
    in.Value(leap, "header");
    in.Value(clock, "header");
    if (in.error.empty() && clock > static_cast<std::uint32_t>(survey::PingClock::kTopsideHeader))
        in.Fail("ping clock " + std::to_string(clock) + " unknown");
    in.Records(r.nav.samples, records::kNavBytes, records::ReadNav, "nav samples");
    in.Records(r.nav.stddevs, records::kStdDevBytes, records::ReadStdDev, "nav stddevs");
    if (format >= 5) {
        in.Records(r.pings.pings, records::kPingBytes, records::ReadPing, "pings");
    } else {
        in.Records(r.pings.pings, records::kLegacyPingBytes, records::ReadLegacyPing, "pings");
    }
    in.Vec(r.pings.range_counts, "range counts");
    if (!in.Finish()) return Error{in.error};
    r.pings.clock = static_cast<survey::PingClock>(clock);
    std::uint64_t next_offset = 0;  // the writer lays each ping's beams after the previous's
    for (const auto& p : r.pings.pings) {
        if (static_cast<std::uint64_t>(p.beam_offset) + p.num_beams > r.pings.range_counts.size())
            return Error{"section ingest: inconsistent beam offsets"};
        // Two pings sharing range counts would be georeferenced into the same slots at once.
        if (p.beam_offset < next_offset)
            return Error{"section ingest: overlapping or out-of-order beam offsets"};
        next_offset = static_cast<std::uint64_t>(p.beam_offset) + p.num_beams;
    }
    r.nav.leap_seconds = leap;
    return Ok{};
}

// ---- intensities ----

Payload IntensityPayload(const survey::PingSeries& p) {
    Payload out;
    out.Vec(p.intensities);
    return out;
}

Status IntensityFromPayload(const std::vector<std::uint8_t>& bytes, survey::PingSeries& p) {
    Cursor in(bytes, "intensity");
    in.Vec(p.intensities, "intensities");
    if (!in.Finish()) return Error{in.error};
    return Ok{};
}

// ---- beam angles ----

Payload BeamAnglePayload(const survey::PingSeries& p) {
    Payload out;
    out.Vec(p.beam_angles_deg);
    return out;
}

Status BeamAngleFromPayload(const std::vector<std::uint8_t>& bytes, survey::PingSeries& p) {
    Cursor in(bytes, "beam_angle");
    in.Vec(p.beam_angles_deg, "beam angles");
    if (!in.Finish()) return Error{in.error};
    return Ok{};
}

// ---- the cleaning's flags ----

// Sparse: the indices (in the range counts) of the soundings the cleaning rejected, ascending,
// and their status.
Payload CleaningPayload(const std::vector<std::uint8_t>& cleaning) {
    std::vector<std::uint32_t> index;
    std::vector<std::uint8_t> code;
    for (std::size_t j = 0; j < cleaning.size(); ++j) {
        if (cleaning[j] == 0) continue;
        index.push_back(static_cast<std::uint32_t>(j));
        code.push_back(cleaning[j]);
    }
    Payload out;
    out.Value(static_cast<std::uint64_t>(cleaning.size()));
    out.Vec(index);
    out.Vec(code);
    return out;
}

// `max_soundings`: the most range counts the file could hold (each takes 4 bytes of it): a
// larger count is corrupt, and is refused before the flags are allocated.
Status CleaningFromPayload(const std::vector<std::uint8_t>& bytes,
                           std::uint64_t max_soundings,
                           std::vector<std::uint8_t>& cleaning) {
    Cursor in(bytes, "cleaning");
    std::uint64_t n = 0;
    std::vector<std::uint32_t> index;
    std::vector<std::uint8_t> code;
    in.Value(n, "sounding count");
    in.Vec(index, "indices");
    in.Vec(code, "statuses");
    if (!in.Finish()) return Error{in.error};
    if (index.size() != code.size())
        return Error{"section cleaning: " + std::to_string(index.size()) + " indices for " +
                     std::to_string(code.size()) + " statuses"};
    if (n > (std::uint64_t{1} << 32) || n > max_soundings)
        return Error{"section cleaning: sounding count " + std::to_string(n) +
                     " too large for the file"};
    cleaning.assign(n, 0);
    for (std::size_t i = 0; i < index.size(); ++i) {
        if (index[i] >= n || (i > 0 && index[i] <= index[i - 1]))
            return Error{"section cleaning: index " + std::to_string(index[i]) +
                         " out of order or beyond " + std::to_string(n) + " soundings"};
        if (!survey::IsSoundingStatus(code[i]) ||
            !survey::IsCleaningStatus(static_cast<survey::SoundingStatus>(code[i])))
            return Error{"section cleaning: status " + std::to_string(code[i]) +
                         " is not a cleaning status"};
        cleaning[index[i]] = code[i];
    }
    return Ok{};
}

// ---- trajectories ----

Payload TrajectoryPayload(const PingTrajectory& t) {
    std::vector<DiskPose> d(t.T_world_vehicle.size());
    for (std::size_t i = 0; i < d.size(); ++i) {
        const Eigen::Vector3d x = t.T_world_vehicle[i].translation();
        const Eigen::Quaterniond q(t.T_world_vehicle[i].rotation());
        d[i] = {{x.x(), x.y(), x.z(), q.w(), q.x(), q.y(), q.z()},
                i < t.valid.size() ? t.valid[i] : 0u,
                0u};
    }
    Payload p;
    p.Vec(d);
    return p;
}

Status TrajectoryFromPayload(const std::vector<std::uint8_t>& bytes,
                             const std::string& tag,
                             PingTrajectory& t) {
    Cursor in(bytes, tag);
    std::vector<DiskPose> d;
    in.Vec(d, "poses");
    if (!in.Finish()) return Error{in.error};
    t.T_world_vehicle.resize(d.size());
    t.valid.resize(d.size());
    for (std::size_t i = 0; i < d.size(); ++i) {
        for (double v : d[i].v) {
            if (!std::isfinite(v)) return Error{"section " + tag + ": a pose is not finite"};
        }
        Eigen::Quaterniond q(d[i].v[3], d[i].v[4], d[i].v[5], d[i].v[6]);
        if (std::abs(q.norm() - 1.0) > 1e-6)
            return Error{"section " + tag + ": a rotation is not a unit quaternion"};
        Pose T = Pose::Identity();
        T.linear() = q.normalized().toRotationMatrix();
        T.translation() = Eigen::Vector3d(d[i].v[0], d[i].v[1], d[i].v[2]);
        t.T_world_vehicle[i] = T;
        t.valid[i] = d[i].valid != 0 ? 1 : 0;
    }
    return Ok{};
}

using DiskSigma = std::array<double, 6>;
constexpr const char* kSlamSigmaTag = "traj.slam.sigma";

Payload SigmaPayload(const PingTrajectory& t) {
    Payload p;
    p.Vec(t.sigma);
    return p;
}

// Into t.sigma; its count is checked against the poses once every section is read.
Status SigmaFromPayload(const std::vector<std::uint8_t>& bytes, PingTrajectory& t) {
    Cursor in(bytes, kSlamSigmaTag);
    std::vector<DiskSigma> d;
    in.Vec(d, "sigmas");
    if (!in.Finish()) return Error{in.error};
    for (const DiskSigma& s : d) {
        for (double v : s) {
            if (!(std::isnan(v) || (std::isfinite(v) && v >= 0))) {
                return Error{std::string("section ") + kSlamSigmaTag +
                             ": a sigma is negative or infinite"};
            }
        }
    }
    t.sigma = std::move(d);
    return Ok{};
}

std::uint64_t FileSize(std::FILE* f) {
    struct stat st {};
    if (fstat(fileno(f), &st) != 0 || st.st_size < 0) return 0;
    return static_cast<std::uint64_t>(st.st_size);
}

bool WriteSection(std::FILE* f, const char* tag, const std::vector<std::uint8_t>& payload) {
    if (std::strlen(tag) >= kTagBytes) return false;  // a tag the reader would not recognise
    char t[kTagBytes] = {};
    std::strncpy(t, tag, kTagBytes - 1);
    const std::uint64_t n = payload.size();
    const std::uint32_t crc = Crc(payload);
    return std::fwrite(t, 1, kTagBytes, f) == kTagBytes && std::fwrite(&n, sizeof n, 1, f) == 1 &&
           std::fwrite(&crc, sizeof crc, 1, f) == 1 &&
           (n == 0 || std::fwrite(payload.data(), 1, n, f) == n);
}

}  // namespace

Status SaveSurvey(const std::string& path, const SurveyModel& m) {
    // Each section's payload is made when it is written and dropped after: the file is never
    // held whole beside the model (its largest section is: the ingest's range counts).
    std::vector<std::pair<const char*, std::function<Payload()>>> sections;
    sections.emplace_back("state", [&m] {
        Payload state;
        const std::string text = StateJson(m).dump();
        state.Bytes(text.data(), text.size());
        return state;
    });
    sections.emplace_back("ingest", [&m] { return IngestPayload(m.ingest); });
    if (m.ingest.pings.has_intensities())
        sections.emplace_back("intensity", [&m] { return IntensityPayload(m.ingest.pings); });
    if (m.ingest.pings.has_beam_angles())
        sections.emplace_back("beam_angle", [&m] { return BeamAnglePayload(m.ingest.pings); });
    if (!m.flags.cleaning.empty())
        sections.emplace_back("cleaning", [&m] { return CleaningPayload(m.flags.cleaning); });
    for (int v = 0; v < kNumTrajectoryVersions; ++v) {
        if (!m.trajectories[v].empty()) {
            sections.emplace_back(kTrajectoryTags[v],
                                  [&m, v] { return TrajectoryPayload(m.trajectories[v]); });
        }
    }
    if (const PingTrajectory& t = m.trajectory(TrajectoryVersion::kSlam);
        !t.empty() && !t.sigma.empty()) {
        sections.emplace_back(kSlamSigmaTag, [&t] { return SigmaPayload(t); });
    }
    const std::string partial = path + ".partial";
    std::FILE* f = std::fopen(partial.c_str(), "wb");
    if (f == nullptr) return Error{formats::ErrnoMessage(partial, "cannot create", errno)};
    const std::uint32_t head[3] = {
        kSurveyFormatVersion, kByteOrder, static_cast<std::uint32_t>(sections.size())};
    bool ok = std::fwrite(kMagic, 1, sizeof kMagic, f) == sizeof kMagic &&
              std::fwrite(head, sizeof head, 1, f) == 1;
    for (const auto& [tag, make] : sections) ok = ok && WriteSection(f, tag, make().bytes());
    ok = ok && std::fflush(f) == 0 && std::ferror(f) == 0;
    int err = errno;
    if (std::fclose(f) != 0 || !ok) {
        if (ok) err = errno;
        std::error_code ec;
        fs::remove(partial, ec);
        return Error{formats::ErrnoMessage(path, "write failed", err) +
                     "; the previous survey file is kept"};
    }
    std::error_code ec;
    fs::rename(partial, path, ec);
    if (ec) return Error{path + ": cannot replace: " + ec.message()};
    return Ok{};
}

namespace {

// The sections a file held so far (each at most once).
struct SeenSections {
    bool state = false, ingest = false, intensity = false, angles = false, cleaning = false;
    bool slam_sigma = false;
    bool trajectory[kNumTrajectoryVersions] = {};

    // The flag of section `tag` in a file of `format`; null for a section unknown there.
    bool* Of(const std::string& tag, std::uint32_t format, int trajectory_index) {
        return tag == "state"                        ? &state
               : tag == "ingest"                     ? &ingest
               : tag == "intensity" && format >= 2   ? &intensity
               : tag == "beam_angle" && format >= 3  ? &angles
               : tag == "cleaning" && format >= 4    ? &cleaning
               : tag == kSlamSigmaTag && format >= 6 ? &slam_sigma
               : trajectory_index >= 0               ? &trajectory[trajectory_index]
                                                     : nullptr;
    }
};

// The trajectory version a section tag names, -1 for none.
int TrajectoryIndex(const std::string& tag) {
    int trajectory = -1;
    for (int v = 0; v < kNumTrajectoryVersions; ++v) {
        if (tag == kTrajectoryTags[v]) trajectory = v;
    }
    return trajectory;
}

// One section's payload into the model (file_size bounds the cleaning section's count).
Status DecodeSection(const std::string& tag,
                     const std::vector<std::uint8_t>& payload,
                     std::uint32_t format,
                     std::uint64_t file_size,
                     SurveyModel& m) {
    if (tag == "state") {
        const json j = json::parse(payload.begin(), payload.end(), nullptr, false);
        Status st = j.is_discarded() || !j.is_object() ? Status(Error{"not a JSON object"})
                                                       : StateFromJson(j, m);
        if (!st) st = Error{"section state: " + st.error().message};
        return st;
    }
    if (tag == "ingest") return IngestFromPayload(payload, format, m.ingest);
    if (tag == "intensity") return IntensityFromPayload(payload, m.ingest.pings);
    if (tag == "beam_angle") return BeamAngleFromPayload(payload, m.ingest.pings);
    if (tag == "cleaning") {
        return CleaningFromPayload(payload, file_size / sizeof(std::uint32_t), m.flags.cleaning);
    }
    if (tag == kSlamSigmaTag)
        return SigmaFromPayload(payload, m.trajectory(TrajectoryVersion::kSlam));
    return TrajectoryFromPayload(payload, tag, m.trajectories[TrajectoryIndex(tag)]);
}

// The per-sounding and per-ping sections against the ingested series: what does not match,
// empty when all do.
std::string SectionSizeMismatch(const SurveyModel& m, const SeenSections& seen) {
    const auto& pings = m.ingest.pings;
    if (seen.intensity && pings.intensities.size() != pings.range_counts.size()) {
        return "section intensity has " + std::to_string(pings.intensities.size()) +
               " intensities for " + std::to_string(pings.range_counts.size()) + " range counts";
    }
    if (seen.angles && pings.beam_angles_deg.size() != pings.range_counts.size()) {
        return "section beam_angle has " + std::to_string(pings.beam_angles_deg.size()) +
               " angles for " + std::to_string(pings.range_counts.size()) + " range counts";
    }
    if (seen.cleaning && m.flags.cleaning.size() != pings.range_counts.size()) {
        return "section cleaning has " + std::to_string(m.flags.cleaning.size()) +
               " soundings for " + std::to_string(pings.range_counts.size()) + " range counts";
    }
    for (int v = 0; v < kNumTrajectoryVersions; ++v) {
        if (seen.trajectory[v] &&
            m.trajectories[v].T_world_vehicle.size() != m.ingest.pings.pings.size()) {
            return std::string("section ") + kTrajectoryTags[v] + " has " +
                   std::to_string(m.trajectories[v].T_world_vehicle.size()) + " poses for " +
                   std::to_string(m.ingest.pings.pings.size()) + " pings";
        }
    }
    if (seen.slam_sigma) {
        const PingTrajectory& t = m.trajectory(TrajectoryVersion::kSlam);
        if (t.sigma.size() != t.T_world_vehicle.size()) {
            return std::string("section ") + kSlamSigmaTag + " has " +
                   std::to_string(t.sigma.size()) + " sigmas for " +
                   std::to_string(t.T_world_vehicle.size()) + " poses of " +
                   kTrajectoryTags[static_cast<int>(TrajectoryVersion::kSlam)];
        }
    }
    return "";
}

}  // namespace

Expected<SurveyModel> LoadSurvey(const std::string& path, LoadParts parts) {
    const std::string rerun = " (run `pitmap georef` again)";
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (f == nullptr) return Error{path + ": cannot open (run `pitmap georef` first)"};
    struct Closer {
        std::FILE* f;
        ~Closer() { std::fclose(f); }
    } closer{f};
    const std::uint64_t size = FileSize(f);
    if (size < kHeadBytes) {
        return Error{path + ": not a pitmap survey file (" + std::to_string(size) + " bytes)" +
                     rerun};
    }
    char magic[sizeof kMagic];
    std::uint32_t head[3] = {0, 0, 0};
    if (std::fread(magic, 1, sizeof magic, f) != sizeof magic ||
        std::fread(head, sizeof head, 1, f) != 1) {
        return Error{path + ": read error" + rerun};
    }
    if (std::memcmp(magic, kMagic, sizeof kMagic) != 0)
        return Error{path + ": not a pitmap survey file (bad magic)" + rerun};
    // Formats 1 to 3 differ only by lacking the intensity, beam_angle and cleaning sections:
    // they are read without them.
    if (head[0] < 1 || head[0] > kSurveyFormatVersion || head[1] != kByteOrder) {
        return Error{path + ": survey file format " + std::to_string(head[0]) +
                     " or byte order not of this build (format " +
                     std::to_string(kSurveyFormatVersion) + ")" + rerun};
    }
    const std::uint32_t format = head[0];
    const std::uint32_t count = head[2];
    std::uint64_t pos = kHeadBytes;
    SurveyModel m;
    SeenSections seen;
    auto corrupt = [&](const std::string& what) {
        return Error{path + ": corrupt survey file: " + what + rerun};
    };
    for (std::uint32_t s = 0; s < count; ++s) {
        if (size - pos < kSectionHeadBytes) return corrupt("truncated in a section header");
        char raw_tag[kTagBytes + 1] = {};
        std::uint64_t n = 0;
        std::uint32_t crc = 0;
        if (std::fread(raw_tag, 1, kTagBytes, f) != kTagBytes ||
            std::fread(&n, sizeof n, 1, f) != 1 || std::fread(&crc, sizeof crc, 1, f) != 1) {
            return Error{path + ": read error" + rerun};
        }
        pos += kSectionHeadBytes;
        const std::string tag(raw_tag, strnlen(raw_tag, kTagBytes));
        if (n > size - pos) {
            return corrupt("section " + tag + " claims " + std::to_string(n) + " bytes, " +
                           std::to_string(size - pos) + " remain");
        }
        bool* seen_flag = seen.Of(tag, format, TrajectoryIndex(tag));
        if (seen_flag == nullptr) return corrupt("unknown section \"" + tag + "\"");
        if (*seen_flag) return corrupt("section " + tag + " twice");
        *seen_flag = true;
        if (parts == LoadParts::kState && tag != "state") {
            if (std::fseek(f, static_cast<long>(n), SEEK_CUR) != 0)
                return Error{path + ": read error" + rerun};
            pos += n;
            continue;
        }
        std::vector<std::uint8_t> payload(n);
        if (n > 0 && std::fread(payload.data(), 1, n, f) != n)
            return Error{path + ": read error" + rerun};
        pos += n;
        if (Crc(payload) != crc) return corrupt("section " + tag + ": checksum mismatch");
        if (Status st = DecodeSection(tag, payload, format, size, m); !st)
            return corrupt(st.error().message);
    }
    if (pos != size) return corrupt(std::to_string(size - pos) + " bytes after the last section");
    if (!seen.state) return corrupt("no state section");
    if (!seen.ingest) return corrupt("no ingest section");
    if (parts == LoadParts::kAll) {
        if (const std::string bad = SectionSizeMismatch(m, seen); !bad.empty()) return corrupt(bad);
    }
    return m;
}

}  // namespace pitmap::proc::survey
