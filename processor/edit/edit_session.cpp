// SPDX-License-Identifier: MIT
#include "processor/edit/edit_session.hpp"

#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <limits>

#include "common/vehicle.hpp"
#include "processor/georef/survey_view.hpp"
#include "processor/hydro/tpu.hpp"
#include "processor/io/svp_files.hpp"
#include "processor/survey/survey_file.hpp"

namespace pitmap::proc::edit {

namespace {

using survey::ManualEdit;
using survey::SoundingStatus;

std::string NowUtc() {
    const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

template <typename T>
std::string Bytes(const std::vector<T>& v, std::size_t stride, std::size_t per) {
    std::string out;
    const std::size_t n = (v.size() / per + stride - 1) / stride;
    out.resize(n * per * sizeof(T));
    char* o = out.data();
    for (std::size_t i = 0; i < v.size() / per; i += stride) {
        std::memcpy(o, &v[i * per], per * sizeof(T));
        o += per * sizeof(T);
    }
    return out;
}

// The TVU (95 %) of every point of `geo`, the grid stage's way: the INS's sigma nearest each
// ping, else the vehicle file's error model.
std::vector<float> Tvu(const georef::GeorefResult& geo,
                       const survey::SurveyModel& m,
                       const SensorErrorModel& model,
                       const EditSessionConfig& c) {
    hydro::TpuConfig tc;
    tc.model = model;
    tc.sound_speed_mps = c.tpu_sound_speed_mps;
    tc.clock_sigma_s = std::abs(m.clock.sigma_s());
    tc.num_threads = c.num_threads;
    if (!tc.Validate().empty() || geo.points.size() == 0) return {};
    const hydro::PingSigma fallback = hydro::FallbackSigma(model);
    std::vector<hydro::PingSigma> sig(geo.pings.size());
    for (std::size_t k = 0; k < sig.size(); ++k) {
        sig[k] = hydro::InsSigmaAt(
            m.ingest.nav.stddevs, geo.pings[k].utime_gps, c.ins_sigma_max_age_s, fallback);
    }
    return hydro::ComputeTpu(geo, m.mount, sig, tc).tvu_95_m;
}

}  // namespace

std::vector<std::string> EditSessionConfig::Validate() const {
    std::vector<std::string> p = georef.Validate();
    if (max_display_points < 1000) p.push_back("edit: max_display_points must be >= 1000");
    if (!(tpu_sound_speed_mps > 0)) p.push_back("edit: tpu_sound_speed_mps must be > 0");
    if (!(ins_sigma_max_age_s >= 0)) p.push_back("edit: ins_sigma_max_age_s must be >= 0");
    if (num_threads < 0) p.push_back("edit: num_threads must be >= 0");
    return p;
}

SoundingStatus EffectiveStatus(SoundingStatus automatic, ManualEdit manual) {
    // survey::Resolve with georef's own verdict and the cleaning's told apart (a cleaning
    // status means georef accepted the sounding); no allocation: called per sounding.
    if (automatic == SoundingStatus::kNoDetection || automatic == SoundingStatus::kRefraction)
        return automatic;
    if (manual == ManualEdit::kRestore) return SoundingStatus::kAccepted;
    if (manual == ManualEdit::kReject) {
        return automatic == SoundingStatus::kRangeGate || automatic == SoundingStatus::kSpike
                   ? automatic
                   : SoundingStatus::kManual;
    }
    return automatic;
}

Expected<std::unique_ptr<EditSession>> EditSession::Open(const std::string& out_dir,
                                                         const EditSessionConfig& config) {
    auto model = survey::LoadSurvey(out_dir + "/" + survey::kSurveyFileName);
    if (!model) return model.error();
    return FromModel(std::move(*model), out_dir, config);
}

Expected<std::unique_ptr<EditSession>> EditSession::FromModel(survey::SurveyModel model,
                                                              const std::string& out_dir,
                                                              const EditSessionConfig& config) {
    PITMAP_CHECK(config.Validate().empty(), "EditSessionConfig::Validate() must be empty");
    std::unique_ptr<EditSession> s(new EditSession());
    s->config_ = config;
    s->out_dir_ = out_dir;
    const std::string log_path = s->edit_log_path();
    // The edit log first: a bad one stops before the (long) georeferencing.
    std::error_code ec;
    if (std::filesystem::exists(log_path, ec)) {
        auto log = survey::ReadEditLog(log_path);
        if (!log) return log.error();
        auto manual = survey::ApplyEditLog(*log, model.ingest.pings, log_path);
        if (!manual) return manual.error();
        s->log_ = std::move(*log);
        s->manual_ = std::move(*manual);
    } else {
        s->log_.survey = survey::IdentityOf(model.ingest.pings);
        s->manual_.assign(model.ingest.pings.num_soundings(), 0);
    }
    auto refraction = io::BuildRefraction(model.refraction);
    if (!refraction) {
        return Error{out_dir + "/" + survey::kSurveyFileName +
                     ": the sound-velocity casts georef used: " + refraction.error().message};
    }
    SensorErrorModel error_model;
    std::string tvu_source = "the default sensor error model";
    if (!model.vehicle_yaml.empty()) {
        if (auto v = ReadVehicleFile(model.vehicle_yaml); v) {
            error_model = v->ErrorModel();
            if (v->uncertainty) tvu_source = "the vehicle file's uncertainty";
        } else {
            tvu_source = "the default sensor error model (the vehicle file is unreadable)";
        }
    }
    // Automatic statuses: no hand edit in the views.
    model.flags.manual.clear();
    const survey::TrajectoryVersion version = model.latest();
    std::vector<double> sum(3, 0.0);
    bool centred = false;
    for (const auto view : {survey::SoundingView::kAccepted, survey::SoundingView::kRejected}) {
        georef::GeorefResult geo =
            georef::Georeference(model, version, config.georef, *refraction, {}, nullptr, view);
        const std::size_t n = geo.points.size();
        if (!centred && n > 0) {
            // The centre: the first view's mean, to the metre (float32 keeps millimetres
            // within kilometres of it).
            Eigen::Vector3d mean = Eigen::Vector3d::Zero();
            for (const auto& p : geo.points.position_world) mean += p;
            mean /= static_cast<double>(n);
            for (int a = 0; a < 3; ++a) s->centre_[a] = std::round(mean[a]);
            centred = true;
        }
        std::vector<float> tvu;
        if (config.compute_tvu) tvu = Tvu(geo, model, error_model, config);
        const std::size_t base = s->flat_.size();
        s->xyz_.resize(3 * (base + n));
        s->flat_.resize(base + n);
        s->auto_status_.resize(base + n);
        s->tvu_.resize(base + n, std::numeric_limits<float>::quiet_NaN());
        for (std::size_t i = 0; i < n; ++i) {
            const Eigen::Vector3d& p = geo.points.position_world[i];
            for (int a = 0; a < 3; ++a)
                s->xyz_[3 * (base + i) + a] = static_cast<float>(p[a] - s->centre_[a]);
            const auto& header =
                model.ingest.pings.pings[geo.pings[geo.points.ping[i]].header_index];
            s->flat_[base + i] = header.beam_offset + geo.points.beam[i];
            s->auto_status_[base + i] =
                view == survey::SoundingView::kAccepted ? 0 : geo.points.status[i];
            if (tvu.size() == n) s->tvu_[base + i] = tvu[i];
        }
        s->has_tvu_ = s->has_tvu_ || tvu.size() == n;
    }
    s->xyz_.shrink_to_fit();
    s->pings_ = std::move(model.ingest.pings);
    s->stride_ = std::max<std::size_t>(
        1, (s->flat_.size() + config.max_display_points - 1) / config.max_display_points);
    s->description_ =
        std::to_string(s->flat_.size()) + " soundings with a position (of " +
        std::to_string(s->pings_.num_soundings()) + ") on the " + survey::ToString(version) +
        " trajectory; " + std::to_string(s->log_.edits.size()) +
        " edit(s) in the log; TVU: " + (s->has_tvu_ ? tvu_source : std::string("not computed"));
    return s;
}

std::vector<std::uint32_t> EditSession::Select(const SelectionQuery& query) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return SelectInPolygon(xyz_.data(), flat_.size(), query, {}, config_.num_threads);
}

Expected<EditOutcome> EditSession::Apply(EditAction action, const SelectionQuery& query) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto t0 = std::chrono::steady_clock::now();
    EditOutcome out;
    const std::vector<std::uint32_t> inside =
        SelectInPolygon(xyz_.data(), flat_.size(), query, {}, config_.num_threads);
    out.selected = inside.size();
    std::vector<std::uint32_t> change;
    for (const std::uint32_t i : inside) {
        const bool accepted = StatusOf(i) == SoundingStatus::kAccepted;
        if (accepted == (action == EditAction::kReject)) change.push_back(flat_[i]);
    }
    out.changed = change.size();
    if (!change.empty()) {
        survey::Edit e;
        e.action = action == EditAction::kReject ? ManualEdit::kReject : ManualEdit::kRestore;
        e.at_utc = NowUtc();
        e.source = config_.source;
        e.runs = survey::RunsOf(pings_, change);
        std::vector<std::uint8_t> before(change.size());
        for (std::size_t k = 0; k < change.size(); ++k) {
            before[k] = manual_[change[k]];
            manual_[change[k]] = static_cast<std::uint8_t>(e.action);
        }
        log_.edits.push_back(std::move(e));
        out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (auto w = SaveLocked(); !w) {
            log_.edits.pop_back();
            for (std::size_t k = 0; k < change.size(); ++k) manual_[change[k]] = before[k];
            return w.error();
        }
    } else {
        out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    out.edits = log_.edits.size();
    return out;
}

Expected<EditOutcome> EditSession::Undo() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (log_.edits.empty()) return Error{"nothing to undo: the edit log has no edit"};
    const auto t0 = std::chrono::steady_clock::now();
    survey::Edit last = std::move(log_.edits.back());
    log_.edits.pop_back();
    auto manual = survey::ApplyEditLog(log_, pings_, edit_log_path());
    PITMAP_CHECK(manual.ok(), "a log that applied applies without its last edit");
    EditOutcome out;
    for (const auto& r : last.runs) out.changed += r.count;
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (auto w = SaveLocked(); !w) {
        log_.edits.push_back(std::move(last));
        return w.error();
    }
    manual_ = std::move(*manual);
    out.edits = log_.edits.size();
    return out;
}

Status EditSession::SaveLocked() {
    return survey::WriteEditLog(edit_log_path(), log_);
}

std::string EditSession::DisplayPositions() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return Bytes(xyz_, stride_, 3);
}

std::string EditSession::DisplayTvu() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return Bytes(tvu_, stride_, 1);
}

std::string EditSession::DisplayStatus() const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::string out;
    out.reserve(flat_.size() / stride_ + 1);
    for (std::size_t i = 0; i < flat_.size(); i += stride_)
        out.push_back(static_cast<char>(StatusOf(i)));
    return out;
}

std::vector<std::uint8_t> EditSession::Statuses() const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<std::uint8_t> out(flat_.size());
    for (std::size_t i = 0; i < flat_.size(); ++i) out[i] = static_cast<std::uint8_t>(StatusOf(i));
    return out;
}

survey::StatusCounts EditSession::Counts() const {
    std::lock_guard<std::mutex> lock(mutex_);
    survey::StatusCounts c{};
    for (std::size_t i = 0; i < flat_.size(); ++i) ++c[static_cast<int>(StatusOf(i))];
    return c;
}

std::size_t EditSession::num_edits() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return log_.edits.size();
}

}  // namespace pitmap::proc::edit
