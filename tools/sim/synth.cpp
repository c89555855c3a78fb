// SPDX-License-Identifier: MIT
#include "tools/sim/synth.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <thread>

#include "common/formats/trajectory_csv.hpp"
#include "common/frames.hpp"
#include "common/gps_time.hpp"
#include "firmware_host/daemon/log_writer.hpp"
#include "firmware_host/daemon/to_lcm.hpp"
#include "lcmtypes/log/channels.hpp"
#include "tools/sim/decoded_channels.hpp"
#include "tools/sim/echo_artifacts.hpp"
#include "tools/sim/nav_errors.hpp"
#include "tools/sim/receiver_sim.hpp"
#include "tools/sim/sonar_model.hpp"
#include "tools/sim/terrain_change.hpp"
#include "tools/sim/trajectory.hpp"
#include "tools/sim/truth_io.hpp"
#include "tools/sim/water_column.hpp"
#include "tools/sim/world.hpp"

namespace pitmap::sim {
namespace {

// The daemon's stamping error of a ping t seconds after the first (its step, if any).
double StampErrorMs(const SonarConfig& o, double t) {
    return o.daemon_stamp_error_step_s >= 0 && t >= o.daemon_stamp_error_step_s
               ? o.daemon_stamp_error_after_ms
               : o.daemon_stamp_error_ms;
}

namespace fs = std::filesystem;

constexpr const char* kNovatelId = "novatel_com1";
constexpr const char* kSonarId = "deltat_udp";
constexpr double kReadTickS = 0.005;  // the daemon's serial reads return every 5 ms

struct Event {
    std::int64_t utime = 0;
    std::string channel;
    std::vector<std::uint8_t> data;
};

std::vector<std::uint8_t> EncodeRaw(std::int64_t utime,
                                    std::int64_t utime_gps,
                                    const std::string& source,
                                    std::string_view protocol,
                                    acq::Transport transport,
                                    std::int64_t seq,
                                    const std::string& peer,
                                    const std::vector<std::uint8_t>& bytes) {
    acq::RawBytesExtra extra;
    extra.utime_gps = utime_gps;
    extra.gps_time_valid = true;
    extra.peer = peer;
    return acq::EncodeLcm(acq::MakeRawBytes(
        utime, source, protocol, transport, seq, std::span<const std::uint8_t>(bytes), extra));
}

// "DD:MM:SS.ss" with a leading '-' for south/west.
std::string Dms(double deg, int width) {
    const double a = std::abs(deg);
    long hundredths = std::lround(a * 3600.0 * 100.0);
    const long d = hundredths / (3600 * 100);
    hundredths -= d * 3600 * 100;
    const long m = hundredths / (60 * 100);
    hundredths -= m * 60 * 100;
    char buf[96];
    std::snprintf(buf,
                  sizeof buf,
                  "%s%0*ld:%02ld:%02ld.%02ld",
                  deg < 0 ? "-" : "",
                  width,
                  d,
                  m,
                  hundredths / 100,
                  hundredths % 100);
    return buf;
}

// The true sound-speed profile as a CARIS .svp cast (taken 10 minutes before the survey at the
// pit centre): truth/water_column.svp, and vendor/<scenario>.svp with the vendor files.
Status WriteTrueCast(const ScenarioConfig& sc,
                     const WaterColumn& water,
                     const fs::path& truth_dir,
                     const fs::path& vendor_dir,
                     std::int64_t start_gps) {
    const std::int64_t unix = UnixFromGps(start_gps - 600LL * 1000000LL);
    const UtcCalendar cal = UtcCalendarFromUnix(unix);
    UtcCalendar jan1;
    jan1.year = cal.year;
    const std::int64_t day0 = UnixFromUtcCalendar(jan1).value_or(unix);
    const long doy = static_cast<long>((unix - day0) / 86400000000LL) + 1;
    std::string text = "[SVP_VERSION_2]\nwater_column.svp\n";
    char buf[160];
    std::snprintf(buf,
                  sizeof buf,
                  "Section %04d-%03ld %02d:%02d:%02d %s %s true cast (pitmap-sim)\n",
                  cal.year,
                  doy,
                  cal.hour,
                  cal.minute,
                  cal.second,
                  Dms(sc.origin_latitude_deg, 2).c_str(),
                  Dms(sc.origin_longitude_deg, 3).c_str());
    text += buf;
    for (const auto& [z, c] : water.Sampled(sc.water.cast_spacing_m, sc.pit.max_depth_m + 10.0)) {
        std::snprintf(buf, sizeof buf, "%.2f %.3f\n", z, c);
        text += buf;
    }
    std::vector<fs::path> paths = {truth_dir / "water_column.svp"};
    if (!vendor_dir.empty()) paths.push_back(vendor_dir / (sc.name + ".svp"));
    for (const fs::path& path : paths) {
        std::ofstream out(path, std::ios::trunc);
        out << text;
        if (!out) return Error{path.string() + ": cannot write"};
    }
    return Ok{};
}

Status WriteVehicleYaml(const fs::path& path, const ScenarioConfig& sc) {
    std::ofstream out(path);
    if (!out) return Error{path.string() + ": cannot create"};
    VehicleDescription v = NominalVehicle(sc);
    v.navigation_channel = kNovatelId;
    v.sonar_channel = kSonarId;
    // The equipment the products' metadata names (the simulator's models of them).
    v.sonar_model = "Imagenex Delta T (pitmap-sim)";
    v.ins_model = "NovAtel SPAN (pitmap-sim)";
    out << "# pitmap vehicle description (schema: `pitmap config --vehicle`), written by "
           "pitmap-sim.\n"
        << FormatVehicleYaml(v);
    return out ? Status(Ok{}) : Status(Error{path.string() + ": write failed"});
}

}  // namespace

Expected<SynthResult> RunSynth(const ScenarioConfig& sc,
                               const SynthOptions& opt,
                               const ProgressCallback& progress) {
    if (auto problems = sc.Validate(); !problems.empty()) {
        std::string msg = "invalid scenario:";
        for (const auto& p : problems) msg += "\n  - " + p;
        return Error{msg};
    }
    auto start_gps = SurveyStartGps(sc);
    if (!start_gps) return start_gps.error();
    const fs::path out(opt.out_dir), log_dir = out / "log", truth_dir = out / "truth";
    std::error_code ec;
    fs::create_directories(log_dir, ec);
    fs::create_directories(truth_dir, ec);
    if (ec || !fs::is_directory(log_dir) || !fs::is_directory(truth_dir)) {
        return Error{opt.out_dir + ": cannot create the output folders"};
    }
    for (const auto& entry : fs::directory_iterator(log_dir)) {
        if (entry.path().extension() == ".lcmlog") {
            return Error{log_dir.string() + " already holds log files; choose an empty --out"};
        }
    }

    // Vendor files: opened before the run so a bad folder fails early.
    std::ofstream vendor_gps, vendor_83p;
    const fs::path vendor_dir = out / "vendor";
    if (opt.vendor_files) {
        fs::create_directories(vendor_dir, ec);
        if (ec || !fs::is_directory(vendor_dir))
            return Error{vendor_dir.string() + ": cannot create"};
        const fs::path gps_path = vendor_dir / (sc.name + ".gps");
        const fs::path p83_path = vendor_dir / (sc.name + ".83P");
        vendor_gps.open(gps_path, std::ios::binary | std::ios::trunc);
        vendor_83p.open(p83_path, std::ios::binary | std::ios::trunc);
        if (!vendor_gps) return Error{gps_path.string() + ": cannot create"};
        if (!vendor_83p) return Error{p83_path.string() + ": cannot create"};
    }
    const auto append = [](std::ofstream& f, const std::vector<std::uint8_t>& bytes) {
        f.write(reinterpret_cast<const char*>(bytes.data()),
                static_cast<std::streamsize>(bytes.size()));
    };

    const PitWorld world = MakeWorld(sc);  // epoch >= 2: with its changes
    auto track = SurveyTrack::Plan(sc);
    if (!track) return track.error();
    const TruthTrajectory truth(sc, *track);
    const NavErrorModel errors(sc.nav, truth.duration_s(), sc.seed);
    std::optional<WaterColumn> water;
    if (sc.water.refraction) {
        // Deep enough for every beam: the deepest terrain plus a margin.
        water.emplace(sc.water, sc.pit.max_depth_m + 10.0);
        if (auto w = WriteTrueCast(
                sc, *water, truth_dir, opt.vendor_files ? vendor_dir : fs::path(), *start_gps);
            !w) {
            return w.error();
        }
    }
    const SonarModel sonar(sc.sonar, world, sc.seed, water ? &*water : nullptr, sc.backscatter);
    // Echo artifacts (issue 35): applied in ping order, after the parallel ray casting.
    EchoArtifactModel echoes(sc.echo_artifacts, sc.sonar, sc.backscatter, world, sc.seed);
    ArtifactTruth artifact_truth;
    artifact_truth.config = sc.echo_artifacts;
    artifact_truth.ping_rate_hz = sc.sonar.ping_rate_hz;
    artifact_truth.first_ping_gps_s = static_cast<double>(*start_gps) * 1e-6;
    SimulatedReceiver receiver(sc, truth, errors, *start_gps);
    const SimulatedTopside topside(sc, truth, *start_gps);
    DecodedChannels decoded(sc);

    // Boresight and lever arm of the sonar: the truth the calibration must find.
    const Eigen::Matrix3d R_vehicle_sonar =
        frames::RotationNedFromRpy(frames::DegToRad(sc.boresight_deg[0]),
                                   frames::DegToRad(sc.boresight_deg[1]),
                                   frames::DegToRad(sc.boresight_deg[2]));
    const Pose T_vehicle_sonar =
        MakePose(R_vehicle_sonar,
                 Eigen::Vector3d(
                     sc.lever_arms.sonar_m[0], sc.lever_arms.sonar_m[1], sc.lever_arms.sonar_m[2]));

    std::atomic<std::int64_t> sim_utime{UnixFromGps(*start_gps)};
    acq::LogWriterConfig lw;
    lw.directory = log_dir.string();
    lw.prefix = "pitmap";
    lw.rotate_bytes = opt.rotate_bytes;
    lw.rotate_interval_s = 0;
    lw.min_free_bytes = 64LL << 20;
    lw.resume_margin_bytes = 16LL << 20;
    if (auto problems = lw.Validate(); !problems.empty())
        return Error{"log writer: " + problems.front()};
    acq::LogWriterHooks hooks;
    hooks.now_utime = [&sim_utime] { return sim_utime.load(); };
    acq::LogWriter writer(lw, hooks);
    if (auto s = writer.Start(); !s) return s.error();

    SynthResult result;
    result.duration_s = truth.duration_s();
    result.track_length_m = truth.duration_s() * sc.track.speed_mps;
    const double byte_time = 10.0 / opt.serial_baud;  // 8N1: 10 bits per byte
    const int threads = opt.num_threads > 0
                            ? opt.num_threads
                            : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    const auto utime_at = [&](double t) { return UnixFromGps(*start_gps + std::llround(t * 1e6)); };
    const auto gps_at = [&](double t) { return *start_gps + std::llround(t * 1e6); };
    std::mt19937_64 jitter_rng(sc.seed ^ 0x1172E7ull);
    std::uniform_real_distribution<double> jitter(0.0002, 0.003);

    double line_free = 0;            // when the serial line is free again
    std::vector<std::uint8_t> line;  // bytes on the line not yet read: (completion time, byte)
    std::vector<double> line_done;
    std::int64_t nov_seq = 0, sonar_seq = 0, next_ping = 0;
    const double block = 1.0;  // seconds per block
    const auto total_pings =
        static_cast<std::int64_t>(std::floor(truth.duration_s() * sc.sonar.ping_rate_hz + 1e-9));
    std::int64_t events_since_flush = 0;
    // The true trajectory at truth_rate_hz, written block by block as the survey is simulated
    // (an hours-long survey's truth is not held: 136 bytes a pose, 25 MB an hour at 50 Hz).
    auto truth_csv = formats::TrajectoryCsvWriter::Open((truth_dir / "trajectory.csv").string());
    if (!truth_csv) return truth_csv.error();
    const double truth_dt = 1.0 / opt.truth_rate_hz;
    double truth_t = 0;  // the next true pose's time: summed as before, the same samples
    const auto write_truth_until = [&](double t_end, bool inclusive) {
        while (truth_t <= truth.duration_s() + 1e-9 && (inclusive || truth_t < t_end)) {
            (*truth_csv)
                ->Append(formats::RowOf(static_cast<double>(gps_at(truth_t)) * 1e-6,
                                        truth.PoseAt(truth_t)));
            truth_t += truth_dt;
        }
    };
    // Insonified area: terrain cells hit by a true beam axis (for the mesh completeness score).
    const TerrainGrid& grid = world.grid();
    std::vector<std::uint8_t> coverage(grid.height_m.size(), 0);

    for (double t0 = 0; t0 < truth.duration_s(); t0 += block) {
        const double t1 = std::min(t0 + block, truth.duration_s());
        std::vector<Event> events;
        // NovAtel: frames onto the serial line, read in 5 ms ticks.
        for (EmittedFrame& f : receiver.Emit(t0, t1)) {
            const double start = std::max(f.t_emit_s, line_free);
            for (std::size_t i = 0; i < f.bytes.size(); ++i) {
                line.push_back(f.bytes[i]);
                line_done.push_back(start + static_cast<double>(i + 1) * byte_time);
            }
            line_free = start + static_cast<double>(f.bytes.size()) * byte_time;
            ++result.novatel_frames;
            if (opt.vendor_files) {
                append(vendor_gps, f.bytes);
                result.vendor_gps_bytes += static_cast<std::int64_t>(f.bytes.size());
            }
        }
        for (double tick = std::ceil(t0 / kReadTickS) * kReadTickS; tick < t1; tick += kReadTickS) {
            std::size_t n = 0;
            while (n < line_done.size() && line_done[n] <= tick) ++n;
            if (n == 0) continue;
            std::vector<std::uint8_t> chunk(line.begin(),
                                            line.begin() + static_cast<std::ptrdiff_t>(n));
            line.erase(line.begin(), line.begin() + static_cast<std::ptrdiff_t>(n));
            line_done.erase(line_done.begin(), line_done.begin() + static_cast<std::ptrdiff_t>(n));
            result.novatel_bytes += static_cast<std::int64_t>(chunk.size());
            const std::int64_t u = utime_at(tick);
            // As the daemon does: the raw chunk first, then what it decodes to.
            auto frames = decoded.NovatelChunk(chunk, u);
            events.push_back({u,
                              lcmlog::ChannelName(lcmlog::kChannelRaw, kNovatelId),
                              EncodeRaw(u,
                                        gps_at(tick),
                                        kNovatelId,
                                        lcmlog::kProtocolNovatel,
                                        acq::Transport::kSerial,
                                        nov_seq++,
                                        "/dev/ttyS1",
                                        chunk)});
            for (auto& [ch, bytes] : frames) events.push_back({u, std::move(ch), std::move(bytes)});
        }
        // Sonar pings of this block, ray cast in parallel (deterministic per ping).
        std::vector<std::int64_t> ping_ids;
        while (next_ping < total_pings &&
               static_cast<double>(next_ping) / sc.sonar.ping_rate_hz < t1) {
            ping_ids.push_back(next_ping++);
        }
        std::vector<SimPing> pings(ping_ids.size());
        std::atomic<std::size_t> next{0};
        auto work = [&] {
            for (std::size_t i = next++; i < ping_ids.size(); i = next++) {
                const double t = static_cast<double>(ping_ids[i]) / sc.sonar.ping_rate_hz;
                pings[i] = sonar.Ping(truth.PoseAt(t) * T_vehicle_sonar, ping_ids[i]);
            }
        };
        std::vector<std::thread> pool;
        for (int k = 1; k < threads; ++k) pool.emplace_back(work);
        work();
        for (auto& th : pool) th.join();
        for (std::size_t i = 0; i < pings.size(); ++i) {
            const double t = static_cast<double>(ping_ids[i]) / sc.sonar.ping_rate_hz;
            {
                const TruthState st = truth.StateAt(t);
                // Body rates, vehicle FRD: z is the yaw rate, y the pitch rate.
                const PingMotion motion{frames::RadToDeg(st.angular_rate_vehicle.z()),
                                        frames::RadToDeg(st.angular_rate_vehicle.y())};
                echoes.Apply(pings[i], st.T_world_vehicle * T_vehicle_sonar, t, motion);
                artifact_truth.Add(pings[i], world);
            }
            for (std::size_t b = 0; b < pings[i].true_range_m.size(); ++b) {
                const float r = pings[i].true_range_m[b];
                if (!std::isfinite(r)) continue;
                const Eigen::Vector3d& hit = pings[i].true_hit_world[b];
                const long ix = std::lround((hit.x() - grid.x0_m) / grid.resolution_m);
                const long iy = std::lround((hit.y() - grid.y0_m) / grid.resolution_m);
                if (ix >= 0 && iy >= 0 && ix < grid.nx && iy < grid.ny)
                    coverage[static_cast<std::size_t>(iy * grid.nx + ix)] = 1;
            }
            TopsideDatagram d = topside.Encode(pings[i], t);
            if (opt.vendor_files) {
                append(vendor_83p, d.bytes);
                result.vendor_83p_bytes += static_cast<std::int64_t>(d.bytes.size());
            }
            const double t_rx = d.t_sent_s + jitter(jitter_rng);
            const std::int64_t u = utime_at(t_rx);
            auto decoded_ping =
                decoded.SonarDatagram(d.bytes, u, gps_at(t + StampErrorMs(sc.sonar, t) * 1e-3));
            events.push_back({u,
                              lcmlog::ChannelName(lcmlog::kChannelRaw, kSonarId),
                              EncodeRaw(u,
                                        gps_at(t_rx),
                                        kSonarId,
                                        lcmlog::kProtocolDeltat83P,
                                        acq::Transport::kUdp,
                                        sonar_seq++,
                                        "127.0.0.1:4040",
                                        d.bytes)});
            for (auto& [ch, bytes] : decoded_ping)
                events.push_back({u, std::move(ch), std::move(bytes)});
            ++result.pings;
        }
        // Time order; stable, so a raw chunk stays ahead of what it decoded to.
        std::stable_sort(events.begin(), events.end(), [](const Event& a, const Event& b) {
            return a.utime < b.utime;
        });
        for (Event& e : events) {
            if (e.channel.empty()) continue;
            sim_utime = e.utime;
            if (++events_since_flush >= 20000) {
                writer.Flush(60000);
                events_since_flush = 0;
            }
            if (!writer.Enqueue(e.utime, e.channel, e.data)) {
                writer.Flush(60000);
                if (!writer.Enqueue(e.utime, std::move(e.channel), std::move(e.data))) {
                    writer.Stop();
                    return Error{"log writer refused an event: " + writer.stats().last_error};
                }
            }
        }
        write_truth_until(t1, false);
        if (progress && !progress(t1 / truth.duration_s())) {
            writer.Stop();
            return Error{"cancelled"};
        }
    }
    // Bytes still on the serial line when the survey ends: the daemon's next read gets them.
    if (!line.empty()) {
        const double tick = std::ceil(line_done.back() / kReadTickS) * kReadTickS;
        const std::int64_t u = utime_at(tick);
        auto frames = decoded.NovatelChunk(line, u);
        result.novatel_bytes += static_cast<std::int64_t>(line.size());
        writer.Enqueue(u,
                       lcmlog::ChannelName(lcmlog::kChannelRaw, kNovatelId),
                       EncodeRaw(u,
                                 gps_at(tick),
                                 kNovatelId,
                                 lcmlog::kProtocolNovatel,
                                 acq::Transport::kSerial,
                                 nov_seq++,
                                 "/dev/ttyS1",
                                 line));
        for (auto& [ch, bytes] : frames) writer.Enqueue(u, std::move(ch), std::move(bytes));
    }
    writer.Stop();
    if (decoded.failures() > 0) {
        return Error{"internal: " + std::to_string(decoded.failures()) +
                     " simulated frames did not decode"};
    }
    const acq::LogWriterStats st = writer.stats();
    if (st.dropped() > 0 || st.write_errors > 0) {
        return Error{"log writer lost events (" + std::to_string(st.dropped()) + " dropped, " +
                     std::to_string(st.write_errors) + " write errors): " + st.last_error};
    }
    result.log_events = st.events_written;
    result.log_bytes = st.bytes_written;
    result.log_files = static_cast<int>(st.files_opened);
    if (auto s = WriteVehicleYaml(log_dir / "vehicle.yaml", sc); !s) return s.error();
    if (opt.vendor_files) {
        vendor_gps.close();
        vendor_83p.close();
        if (!vendor_gps || !vendor_83p)
            return Error{vendor_dir.string() + ": writing the vendor files failed"};
        // Beside them as a surveyor keeps it (sonar clock offset unknown).
        if (auto s = WriteVehicleYaml(vendor_dir / "vehicle.yaml", sc); !s) return s.error();
    }

    // Ground truth.
    write_truth_until(truth.duration_s(), true);
    if (auto s = (*truth_csv)->Finish(); !s) return s.error();
    Truth t;
    t.origin = {sc.origin_latitude_deg, sc.origin_longitude_deg, sc.origin_height_m};
    t.terrain = world.grid();
    t.trajectory_written = true;
    t.boresight = {
        sc.boresight_deg[0], sc.boresight_deg[1], sc.boresight_deg[2], sc.lever_arms.sonar_m};
    t.coverage = std::move(coverage);
    t.backscatter_db =
        SeabedBackscatter(sc.backscatter, sc.seed, world.boulders()).Sample(world.grid());
    t.epoch = sc.epoch;
    t.changes = sc.changes;
    if (!sc.changes.empty()) t.change_m = ChangeGrid(world.grid(), sc.changes);
    t.backscatter = sc.backscatter;
    t.sonar_clock = MakeSonarClockTruth(sc, *start_gps, truth.duration_s());
    result.artifact_soundings = artifact_truth.artifact_soundings();
    if (artifact_truth.pings > 0 && artifact_truth.beams_per_ping > 0) {
        result.artifact_share =
            static_cast<double>(result.artifact_soundings) /
            (static_cast<double>(artifact_truth.pings) * artifact_truth.beams_per_ping);
    }
    t.artifacts = std::move(artifact_truth);
    if (auto s = WriteTruth(truth_dir.string(), sc, t); !s) return s.error();
    return result;
}

}  // namespace pitmap::sim
