// SPDX-License-Identifier: MIT
#include "common/vehicle.hpp"

#include <Eigen/Geometry>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <vector>

#include "common/config.hpp"
#include "common/frames.hpp"

namespace pitmap {

namespace {

// Boresight angles beyond this are a mount, not a residual: they belong in sonar.mount.
constexpr double kMaxBoresightDeg = 15.0;

// Physical bounds of a surface vehicle's layout. A lever arm is a few metres on an ASV and
// some tens on a survey ship: beyond kMaxLeverArmM it is a unit mistake (cm or mm), not a
// vehicle. A transducer deeper than kMaxDraftM below the water line is not on a surface
// vehicle's hull (a towed or ROV-mounted head is not what pitmap georeferences).
constexpr double kMaxLeverArmM = 50.0;
constexpr double kMaxDraftM = 10.0;
// Without the INS height above the water line, the transducer may lie this far above the INS
// reference point (an INS mounted low in a hull) before the sign of z is suspect.
constexpr double kMaxSonarAboveInsM = 2.0;

constexpr SonarOrientation kOrientations[] = {SonarOrientation::kDown, SonarOrientation::kTilted};
constexpr ConnectorDirection kConnectors[] = {ConnectorDirection::kAft,
                                              ConnectorDirection::kForward,
                                              ConnectorDirection::kPort,
                                              ConnectorDirection::kStarboard};
constexpr SoundVelocitySource kSoundVelocitySources[] = {
    SoundVelocitySource::kUnknown, SoundVelocitySource::kProbe, SoundVelocitySource::kManual};

double ConnectorYawDeg(ConnectorDirection c) {
    switch (c) {
        case ConnectorDirection::kAft:
            return 0;
        case ConnectorDirection::kPort:
            return 90;
        case ConnectorDirection::kForward:
            return 180;
        case ConnectorDirection::kStarboard:
            return -90;
    }
    return 0;
}

// The keys of the `uncertainty:` section, in file order, with their comments.
struct ErrorKey {
    const char* key;
    double SensorErrorModel::*field;
    const char* comment;
};
constexpr ErrorKey kErrorKeys[] = {
    {"range_sigma_m", &SensorErrorModel::range_sigma_m, "range noise, constant part, m"},
    {"range_sigma_fraction", &SensorErrorModel::range_sigma_fraction, "range noise, share of r"},
    {"beam_angle_sigma_deg", &SensorErrorModel::beam_angle_sigma_deg, "beam pointing, deg"},
    {"surface_sound_speed_sigma_mps",
     &SensorErrorModel::surface_sound_speed_sigma_mps,
     "at the transducer, m/s"},
    {"mean_sound_speed_sigma_mps",
     &SensorErrorModel::mean_sound_speed_sigma_mps,
     "water column mean, m/s"},
    {"position_sigma_h_m", &SensorErrorModel::position_sigma_h_m, "INS, no INSSTDEV: per axis"},
    {"position_sigma_v_m", &SensorErrorModel::position_sigma_v_m, "INS, no INSSTDEV: height"},
    {"position_noise_m", &SensorErrorModel::position_noise_m, "INS output white noise, m"},
    {"roll_pitch_sigma_deg", &SensorErrorModel::roll_pitch_sigma_deg, "INS, no INSSTDEV"},
    {"heading_sigma_deg", &SensorErrorModel::heading_sigma_deg, "INS, no INSSTDEV"},
    {"heave_sigma_m", &SensorErrorModel::heave_sigma_m, "0 = heights from the INS (RTK)"},
    {"latency_sigma_s", &SensorErrorModel::latency_sigma_s, "sonar-INS timing, s"},
    {"lever_arm_sigma_m", &SensorErrorModel::lever_arm_sigma_m, "per axis, m"},
    {"boresight_sigma_deg", &SensorErrorModel::boresight_sigma_deg, "per axis, deg"},
};

// Reads an enum spelled as one of its ToString names; a problem lists the valid ones.
template <class E, std::size_t N>
bool ReadEnum(ConfigReader& in, const char* key, E& value, const E (&all)[N]) {
    std::string text;
    if (!in.Read(key, text)) return false;
    std::string valid;
    for (E e : all) {
        if (text == ToString(e)) {
            value = e;
            return true;
        }
        valid += std::string(valid.empty() ? "" : " | ") + ToString(e);
    }
    in.AddProblem(in.Path(key) + ": '" + text + "' is not one of " + valid);
    return false;
}

// A list of 3 finite numbers; `what` describes it in a problem.
bool ToVec3(const std::vector<double>& v, Eigen::Vector3d& out) {
    if (v.size() != 3) return false;
    for (double x : v) {
        if (!std::isfinite(x)) return false;
    }
    out = Eigen::Vector3d(v[0], v[1], v[2]);
    return true;
}

bool ReadVec3(ConfigReader& in, const char* key, Eigen::Vector3d& out) {
    std::vector<double> v;
    if (!in.Read(key, v)) return false;
    if (!ToVec3(v, out)) {
        in.AddProblem(in.Path(key) + ": must be 3 finite numbers [x, y, z]");
        return false;
    }
    return true;
}

bool ReadFinite(ConfigReader& in, const char* key, std::optional<double>& out) {
    double v = 0;
    if (!in.Read(key, v)) return false;
    if (!std::isfinite(v)) {
        in.AddProblem(in.Path(key) + ": must be a finite number");
        return false;
    }
    out = v;
    return true;
}

// Prefixes problems that lack the origin (those added with AddProblem) with it.
std::string JoinProblems(const std::vector<std::string>& problems, const std::string& origin) {
    std::vector<std::string> out;
    for (const auto& p : problems) {
        out.push_back(p.rfind(origin, 0) == 0 ? p : origin + ": " + p);
    }
    return FormatProblems(out);
}

// Shortest text that reads back as the same double.
std::string Num(double v) {
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    std::string s(buf, r.ptr);
    return s;
}

std::string Vec(const Eigen::Vector3d& v) {
    return "[" + Num(v.x()) + ", " + Num(v.y()) + ", " + Num(v.z()) + "]";
}

// What a lever arm beyond kMaxLeverArmM most likely is: the same numbers in cm or mm, each
// unit named when it gives a vehicle-sized arm.
std::string UnitHint(const Eigen::Vector3d& v) {
    const double m = v.cwiseAbs().maxCoeff();
    std::vector<std::string> units;
    if (m / 100.0 <= kMaxDraftM) units.push_back("centimetres (" + Vec(v / 100.0) + " m)");
    if (m / 1000.0 <= kMaxDraftM) units.push_back("millimetres (" + Vec(v / 1000.0) + " m)");
    if (units.empty()) return "";
    return "; in " + units[0] + (units.size() > 1 ? " or in " + units[1] : "") + "?";
}

// Lever arms within physical bounds, and the transducer in the water: a value that cannot be
// a surface vehicle's is a problem naming the key, the value and the likely mistake (a sign
// or a unit). z is down in the vehicle frame (docs/conventions.md).
void CheckLayout(ConfigReader& r, const VehicleDescription& v) {
    ConfigReader s = r.Child("sonar");
    ConfigReader g = r.Child("gnss");
    const Eigen::Vector3d& a = v.sonar_lever_arm_m;
    bool sonar_in_bounds = true;
    if (a.cwiseAbs().maxCoeff() > kMaxLeverArmM) {
        sonar_in_bounds = false;
        s.AddProblem(s.Path("lever_arm_m") + ": " + Vec(a) + " is beyond " + Num(kMaxLeverArmM) +
                     " m, not a surface vehicle's lever arm (metres, INS to transducer)" +
                     UnitHint(a));
    }
    for (std::size_t i = 0; i < v.gnss_antenna_lever_arms_m.size(); ++i) {
        const Eigen::Vector3d& b = v.gnss_antenna_lever_arms_m[i];
        if (b.cwiseAbs().maxCoeff() > kMaxLeverArmM) {
            g.AddProblem(g.Path("antenna_lever_arms_m") + "[" + std::to_string(i) + "]: " + Vec(b) +
                         " is beyond " + Num(kMaxLeverArmM) + " m" + UnitHint(b));
        }
    }
    if (!sonar_in_bounds) return;
    const std::string key = s.Path("lever_arm_m");
    if (v.ins_height_above_waterline_m) {
        const double h = *v.ins_height_above_waterline_m;
        const double draft = a.z() - h;  // transducer depth below the water line
        const std::string where = " (z " + Num(a.z()) + " m down from the INS, which is " + Num(h) +
                                  " m above the water line: ins.height_above_waterline_m)";
        if (draft < 0) {
            s.AddProblem(key + ": " + Vec(a) + " puts the transducer " + Num(-draft) +
                         " m above the water line" + where +
                         ": z points down in the vehicle frame (x forward, y starboard); is its "
                         "sign flipped?");
        } else if (draft > kMaxDraftM) {
            s.AddProblem(key + ": " + Vec(a) + " puts the transducer " + Num(draft) +
                         " m below the water line" + where +
                         ", deeper than a surface vehicle's "
                         "hull (" +
                         Num(kMaxDraftM) + " m); z in centimetres? " + Num(a.z()) + " cm is " +
                         Num(a.z() / 100.0) + " m");
        }
        for (std::size_t i = 0; i < v.gnss_antenna_lever_arms_m.size(); ++i) {
            const Eigen::Vector3d& b = v.gnss_antenna_lever_arms_m[i];
            if (b.cwiseAbs().maxCoeff() <= kMaxLeverArmM && b.z() - h > 0) {
                g.AddProblem(g.Path("antenna_lever_arms_m") + "[" + std::to_string(i) +
                             "]: " + Vec(b) + " puts the antenna " + Num(b.z() - h) +
                             " m below the water line: z points down; is its sign flipped?");
            }
        }
    } else if (a.z() < -kMaxSonarAboveInsM) {
        s.AddProblem(key + ": " + Vec(a) + " puts the transducer " + Num(-a.z()) +
                     " m above the INS: z points down in the vehicle frame; is its sign flipped?");
    } else if (a.z() > kMaxDraftM + kMaxSonarAboveInsM) {
        s.AddProblem(key + ": " + Vec(a) + " puts the transducer " + Num(a.z()) +
                     " m below the INS, deeper than a surface vehicle's hull; z in "
                     "centimetres? " +
                     Num(a.z()) + " cm is " + Num(a.z() / 100.0) + " m");
    }
}

// A YAML double-quoted scalar that reads back as `s` (control characters escaped).
std::string Quoted(const std::string& s) {
    std::string q = "\"";
    for (char c : s) {
        const auto u = static_cast<unsigned char>(c);
        if (c == '"' || c == '\\') {
            q += '\\';
            q += c;
        } else if (u < 0x20 || u == 0x7f) {
            char esc[8];
            std::snprintf(esc, sizeof esc, "\\x%02x", u);
            q += esc;
        } else {
            q += c;
        }
    }
    return q + "\"";
}

// Writes every key; with `comments`, the documented template.
std::string Format(const VehicleDescription& v, int indent, bool comments) {
    std::ostringstream o;
    const std::string pad(static_cast<std::size_t>(indent), ' ');
    auto line = [&](const std::string& text, const char* comment) {
        std::string l = pad + text;
        if (comments && *comment != 0) {
            l.resize(std::max<std::size_t>(l.size() + 1, static_cast<std::size_t>(indent) + 34),
                     ' ');
            l += std::string("# ") + comment;
        }
        o << l << "\n";
    };
    auto note = [&](const char* comment, int more_indent = 0) {
        if (comments) o << pad << std::string(more_indent, ' ') << "# " << comment << "\n";
    };
    note("pitmap vehicle description (vehicle.yaml), schema 1. Vehicle frame: x forward,");
    note("y starboard, z down, origin at the INS reference point; metres and degrees.");
    note("R_vehicle_sonar = R_boresight * R_mount (docs/conventions.md, \"Sonar mount\").");
    line("pitmap_vehicle: " + std::to_string(kVehicleSchemaVersion),
         "required: marks a pitmap vehicle file");
    line("name: " + Quoted(v.name), "free text");
    line("sonar:", "");
    line("  lever_arm_m: " + Vec(v.sonar_lever_arm_m),
         "required: transducer in the vehicle frame, m");
    line("  mount:", "required");
    line(std::string("    orientation: ") + ToString(v.orientation),
         "down | tilted (fan turned about the head's x axis)");
    line("    tilt_deg: " + Num(v.tilt_deg),
         "tilted only: 0 < |tilt| <= 90 from nadir, > 0 to sonar +y");
    line(std::string("    connector: ") + ToString(v.connector),
         "aft | forward | port | starboard (the cable)");
    line("  boresight_deg: " + Vec(v.boresight_deg),
         "residual roll, pitch, yaw about the vehicle axes, |a| <= 15");
    note("clock_offset_s: the sonar's (.83P header) clock minus GPS-disciplined UTC, s;", 2);
    note("> 0 = the sonar clock is ahead of UTC, < 0 = behind; null = unknown.", 2);
    line("  clock_offset_s: " +
             (v.sonar_clock_offset_s ? Num(*v.sonar_clock_offset_s) : std::string("null")),
         "sonar clock - UTC, s");
    line(std::string("  sound_velocity_source: ") + ToString(v.sound_velocity_source),
         "probe (at the head) | manual (topside) | unknown");
    line("  channel: " + Quoted(v.sonar_channel), "LCM channel id, \"\" = every one");
    // Optional (issue 39: the products' metadata), written when given: the template printed by
    // `pitmap config --vehicle` is README's block, which does not show them.
    if (!v.sonar_model.empty()) {
        line("  model: " + Quoted(v.sonar_model), "make and model (products' metadata)");
    }
    line("gnss:", "");
    if (v.gnss_antenna_lever_arms_m.empty()) {
        line("  antenna_lever_arms_m: []", "one [x, y, z] per antenna, m");
    } else {
        line("  antenna_lever_arms_m:", "one [x, y, z] per antenna, m");
        for (const auto& a : v.gnss_antenna_lever_arms_m) line("    - " + Vec(a), "");
    }
    line("ins:", "");
    line("  height_above_waterline_m: " + (v.ins_height_above_waterline_m
                                               ? Num(*v.ins_height_above_waterline_m)
                                               : std::string("null")),
         "INS above the water line, m; null = unknown");
    line("  channel: " + Quoted(v.navigation_channel), "LCM channel id, \"\" = every one");
    if (!v.ins_model.empty()) {
        line("  model: " + Quoted(v.ins_model), "GNSS/INS make and model (products' metadata)");
    }
    if (v.uncertainty) {
        note("Sensor error model, 1 sigma (total propagated uncertainty per sounding);");
        note("absent = these defaults (Imagenex Delta T, NovAtel SPAN with RTK).");
        line("uncertainty:", "");
        for (const ErrorKey& k : kErrorKeys) {
            line(std::string("  ") + k.key + ": " + Num((*v.uncertainty).*k.field), k.comment);
        }
    }
    return o.str();
}

}  // namespace

const char* ToString(SonarOrientation o) {
    return o == SonarOrientation::kTilted ? "tilted" : "down";
}

const char* ToString(ConnectorDirection c) {
    switch (c) {
        case ConnectorDirection::kAft:
            return "aft";
        case ConnectorDirection::kForward:
            return "forward";
        case ConnectorDirection::kPort:
            return "port";
        case ConnectorDirection::kStarboard:
            return "starboard";
    }
    return "?";
}

const char* ToString(SoundVelocitySource s) {
    switch (s) {
        case SoundVelocitySource::kUnknown:
            return "unknown";
        case SoundVelocitySource::kProbe:
            return "probe";
        case SoundVelocitySource::kManual:
            return "manual";
    }
    return "?";
}

std::vector<std::string> SensorErrorModel::Validate() const {
    std::vector<std::string> out;
    for (const ErrorKey& k : kErrorKeys) {
        const double x = this->*k.field;
        if (!std::isfinite(x) || x < 0) {
            out.push_back(std::string("uncertainty.") + k.key + ": must be finite and >= 0");
        }
    }
    if (range_sigma_fraction >= 0.1) {
        out.push_back("uncertainty.range_sigma_fraction: must be < 0.1 (a share of the range)");
    }
    return out;
}

Eigen::Matrix3d VehicleDescription::R_vehicle_sonar_nominal() const {
    const double tilt = orientation == SonarOrientation::kTilted ? tilt_deg : 0.0;
    return (Eigen::AngleAxisd(frames::DegToRad(ConnectorYawDeg(connector)),
                              Eigen::Vector3d::UnitZ()) *
            Eigen::AngleAxisd(frames::DegToRad(-tilt), Eigen::Vector3d::UnitX()))
        .toRotationMatrix();
}

Eigen::Matrix3d VehicleDescription::R_vehicle_sonar() const {
    return frames::RotationNedFromRpy(frames::DegToRad(boresight_deg.x()),
                                      frames::DegToRad(boresight_deg.y()),
                                      frames::DegToRad(boresight_deg.z())) *
           R_vehicle_sonar_nominal();
}

void ReadVehicle(ConfigReader& r, VehicleDescription& v) {
    int version = 0;
    if (!r.Has("pitmap_vehicle")) {
        r.AddProblem(r.Path("pitmap_vehicle") + ": required but missing (pitmap_vehicle: " +
                     std::to_string(kVehicleSchemaVersion) + ")");
    }
    if (r.Read("pitmap_vehicle", version) && version != kVehicleSchemaVersion) {
        r.AddProblem(r.Path("pitmap_vehicle") + ": schema " + std::to_string(version) +
                     " is not known to this pitmap (it reads schema " +
                     std::to_string(kVehicleSchemaVersion) + ")");
    }
    r.Read("name", v.name);
    {
        ConfigReader s = r.Child("sonar");
        if (!s.Has("lever_arm_m")) {
            s.AddProblem(s.Path("lever_arm_m") +
                         ": required but missing ([x, y, z] from the INS "
                         "reference point, vehicle frame, m)");
        }
        ReadVec3(s, "lever_arm_m", v.sonar_lever_arm_m);
        ConfigReader m = s.Child("mount");
        if (!m.Has("orientation")) {
            m.AddProblem(m.Path("orientation") + ": required but missing (down | tilted)");
        }
        ReadEnum(m, "orientation", v.orientation, kOrientations);
        if (!m.Has("connector")) {
            m.AddProblem(m.Path("connector") +
                         ": required but missing (aft | forward | port | starboard)");
        }
        ReadEnum(m, "connector", v.connector, kConnectors);
        const bool has_tilt = m.Read("tilt_deg", v.tilt_deg);
        if (v.orientation == SonarOrientation::kTilted) {
            if (!has_tilt) {
                m.AddProblem(m.Path("tilt_deg") + ": required for orientation: tilted");
            } else if (!(std::abs(v.tilt_deg) > 0 && std::abs(v.tilt_deg) <= 90)) {
                m.AddProblem(m.Path("tilt_deg") +
                             ": must be within 0 < |tilt| <= 90 for a tilted "
                             "mount, is " +
                             Num(v.tilt_deg));
            }
        } else if (has_tilt && v.tilt_deg != 0) {
            m.AddProblem(m.Path("tilt_deg") + ": " + Num(v.tilt_deg) +
                         " with orientation: down (use orientation: tilted, or 0)");
        }
        m.RejectUnknownKeys();
        if (ReadVec3(s, "boresight_deg", v.boresight_deg) &&
            v.boresight_deg.cwiseAbs().maxCoeff() > kMaxBoresightDeg) {
            s.AddProblem(s.Path("boresight_deg") + ": " + Vec(v.boresight_deg) + " beyond +-" +
                         Num(kMaxBoresightDeg) +
                         " degrees: describe the mount in sonar.mount (orientation, tilt_deg, "
                         "connector); the boresight is only the small residual");
        }
        ReadFinite(s, "clock_offset_s", v.sonar_clock_offset_s);
        ReadEnum(s, "sound_velocity_source", v.sound_velocity_source, kSoundVelocitySources);
        s.Read("channel", v.sonar_channel);
        s.Read("model", v.sonar_model);
        s.RejectUnknownKeys();
    }
    {
        ConfigReader g = r.Child("gnss");
        std::vector<std::vector<double>> arms;
        if (g.Read("antenna_lever_arms_m", arms)) {
            for (std::size_t i = 0; i < arms.size(); ++i) {
                Eigen::Vector3d a;
                if (!ToVec3(arms[i], a)) {
                    g.AddProblem(g.Path("antenna_lever_arms_m") + "[" + std::to_string(i) +
                                 "]: must be 3 finite numbers [x, y, z]");
                    continue;
                }
                v.gnss_antenna_lever_arms_m.push_back(a);
            }
        }
        g.RejectUnknownKeys();
    }
    {
        ConfigReader n = r.Child("ins");
        ReadFinite(n, "height_above_waterline_m", v.ins_height_above_waterline_m);
        n.Read("channel", v.navigation_channel);
        n.Read("model", v.ins_model);
        n.RejectUnknownKeys();
    }
    if (r.Has("uncertainty")) {
        ConfigReader u = r.Child("uncertainty");
        SensorErrorModel m;
        for (const ErrorKey& k : kErrorKeys) {
            double x = 0;
            if (!u.Read(k.key, x)) continue;
            if (!std::isfinite(x) || x < 0) {
                u.AddProblem(u.Path(k.key) + ": must be a finite number >= 0, is " + Num(x));
                continue;
            }
            m.*k.field = x;
        }
        if (m.range_sigma_fraction >= 0.1) {
            u.AddProblem(u.Path("range_sigma_fraction") + ": " + Num(m.range_sigma_fraction) +
                         " is a share of the range (0.002 = 0.2 %), must be < 0.1");
        }
        u.RejectUnknownKeys();
        v.uncertainty = m;
    }
    CheckLayout(r, v);
    r.RejectUnknownKeys();
}

Expected<VehicleDescription> ParseVehicleYaml(const std::string& text, const std::string& origin) {
    auto reader = ConfigReader::FromString(text, origin);
    if (!reader) return reader.error();
    ConfigReader& r = *reader;
    const std::string hint = " (`pitmap config --vehicle` prints the schema)";
    if (!r.Has("pitmap_vehicle")) {
        // Not ours: say which of the required keys are absent, not every foreign key.
        std::vector<std::string> missing = {"pitmap_vehicle"};
        ConfigReader sonar = r.Child("sonar");
        if (!sonar.Has("lever_arm_m")) missing.push_back("sonar.lever_arm_m");
        ConfigReader mount = sonar.Child("mount");
        if (!mount.Has("orientation")) missing.push_back("sonar.mount.orientation");
        if (!mount.Has("connector")) missing.push_back("sonar.mount.connector");
        std::string msg = origin + ": not a pitmap vehicle file; missing:";
        for (const auto& m : missing) msg += " " + m;
        if (r.Has("lever_arms_m")) {
            msg +=
                "; lever_arms_m is the layout of pitmap before schema 1: move the sonar lever "
                "arm to sonar.lever_arm_m and add pitmap_vehicle: 1 and sonar.mount";
        }
        return Error{msg + hint};
    }
    VehicleDescription v;
    ReadVehicle(r, v);
    if (!r.problems().empty()) {
        return Error{origin + ": invalid vehicle file" + hint + ":\n" +
                     JoinProblems(r.problems(), origin)};
    }
    return v;
}

Expected<VehicleDescription> ReadVehicleFile(const std::string& path) {
    std::ifstream in(path);
    if (!in) return Error{path + ": cannot open"};
    std::stringstream text;
    text << in.rdbuf();
    if (in.bad()) return Error{path + ": read error"};
    return ParseVehicleYaml(text.str(), path);
}

std::string FormatVehicleYaml(const VehicleDescription& v, int indent) {
    return Format(v, indent, false);
}

std::string VehicleYamlTemplate() {
    VehicleDescription v;
    v.name = "my-asv";
    v.sonar_lever_arm_m = Eigen::Vector3d(0.95, 0.0, 0.62);
    v.gnss_antenna_lever_arms_m = {Eigen::Vector3d(0.42, -0.31, -1.25)};
    v.ins_height_above_waterline_m = 0.35;
    v.uncertainty = SensorErrorModel{};
    return Format(v, 0, true);
}

}  // namespace pitmap
