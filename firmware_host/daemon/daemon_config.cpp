// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/daemon_config.hpp"

#include <sys/stat.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <set>
#include <sstream>

#include "common/config.hpp"
#include "common/vehicle.hpp"
#include "firmware_host/daemon/startup_check.hpp"
#include "lcmtypes/log/channels.hpp"

namespace pitmap::acq {
namespace {

void Append(std::vector<std::string>& to,
            const std::string& prefix,
            const std::vector<std::string>& from) {
    for (const auto& p : from) to.push_back(prefix + ": " + p);
}

void ReadChannel(ConfigReader& r, ChannelSpec& spec, std::vector<std::string>& problems) {
    SensorChannelConfig& c = spec.channel;
    std::string base = r.Path("id");
    base.resize(base.size() - 3);  // "channels[i]"
    r.Require("id", c.id);
    std::string protocol;
    if (r.Require("protocol", protocol)) {
        if (protocol == lcmlog::kProtocolNovatel) {
            c.protocol = ChannelProtocol::kNovatel;
        } else if (protocol == lcmlog::kProtocolDeltat83P) {
            c.protocol = ChannelProtocol::kDeltat83P;
        } else {
            r.AddProblem(r.Path("protocol") + ": '" + protocol + "' is not one of " +
                         std::string(lcmlog::kProtocolNovatel) + ", " +
                         std::string(lcmlog::kProtocolDeltat83P));
        }
    }
    int sources = 0;
    if (r.Has("serial")) {
        ++sources;
        spec.kind = SourceKind::kSerial;
        ConfigReader s = r.Child("serial");
        s.Require("path", spec.serial.path);
        s.Read("baud", spec.serial.baud);
        s.Read("rtscts", spec.serial.rtscts);
        s.Read("exclusive", spec.serial.exclusive);
        s.RejectUnknownKeys();
        Append(problems, r.Path("serial"), spec.serial.Validate());
    }
    if (r.Has("tcp")) {
        ++sources;
        spec.kind = SourceKind::kTcp;
        ConfigReader s = r.Child("tcp");
        s.Require("host", spec.tcp.host);
        s.Require("port", spec.tcp.port);
        s.Read("connect_timeout_ms", spec.tcp.connect_timeout_ms);
        s.RejectUnknownKeys();
        Append(problems, r.Path("tcp"), spec.tcp.Validate());
    }
    if (r.Has("udp")) {
        ++sources;
        spec.kind = SourceKind::kUdp;
        ConfigReader s = r.Child("udp");
        s.Read("bind_address", spec.udp.bind_address);
        s.Require("port", spec.udp.port);
        s.Read("receive_buffer_bytes", spec.udp.receive_buffer_bytes);
        // Required and non-empty: the daemon never takes sensor data from just anyone.
        if (s.Require("allowed_senders", spec.udp.allowed_senders) &&
            spec.udp.allowed_senders.empty()) {
            s.AddProblem(s.Path("allowed_senders") +
                         ": must list the sender(s), e.g. [\"192.168.0.4\"]");
        }
        s.Read("reply_to", spec.udp.reply_to);
        s.RejectUnknownKeys();
        Append(problems, r.Path("udp"), spec.udp.Validate());
    }
    if (r.Has("file")) {
        ++sources;
        spec.kind = SourceKind::kFile;
        ConfigReader s = r.Child("file");
        s.Require("path", spec.file.path);
        s.Read("chunk_bytes", spec.file.chunk_bytes);
        s.Read("bytes_per_second", spec.file.bytes_per_second);
        s.RejectUnknownKeys();
        Append(problems, r.Path("file"), spec.file.Validate());
    }
    if (sources != 1) {
        r.AddProblem(base + ": needs exactly one of serial, tcp, udp, file (found " +
                     std::to_string(sources) + ")");
    }
    r.Read("read_timeout_ms", c.read_timeout_ms);
    r.Read("silent_timeout_ms", c.silent_timeout_ms);
    r.Read("setup_commands", c.setup_commands);
    r.Read("command_timeout_ms", c.command_timeout_ms);
    r.Read("command_retries", c.command_retries);
    r.Read("imu_type", c.imu.imu_type);
    r.Read("imu_rate_hz", c.imu.imu_rate_hz);
    r.Read("corrimu_rate_hz", c.imu.corrimu_rate_hz);
    if (r.Has("ec")) {
        ConfigReader e = r.Child("ec");
        e.Read("enabled", c.ec.enabled);
        int range_m = c.ec.frame.range_m;
        int gain = c.ec.frame.start_gain_db;
        int display = c.ec.frame.display_gain_pct;
        int sector = c.ec.frame.sector_deg;
        int beams = c.ec.frame.num_beams;
        e.Read("range_m", range_m);
        e.Read("start_gain_db", gain);
        e.Read("display_gain_pct", display);
        e.Read("sector_deg", sector);
        e.Read("num_beams", beams);
        e.Read("interval_ms", c.ec.interval_ms);
        e.RejectUnknownKeys();
        if (range_m < 0 || range_m > 65535 || gain < 0 || gain > 40 || display < 0 ||
            display > 100 || sector < 0 || sector > 65535 || beams < 0 || beams > 65535) {
            e.AddProblem(r.Path("ec") +
                         ": value out of range (start_gain_db 0..40, "
                         "display_gain_pct 0..100)");
        } else {
            c.ec.frame.range_m = static_cast<std::uint16_t>(range_m);
            c.ec.frame.start_gain_db = static_cast<std::uint8_t>(gain);
            c.ec.frame.display_gain_pct = static_cast<std::uint8_t>(display);
            c.ec.frame.sector_deg = static_cast<std::uint16_t>(sector);
            c.ec.frame.num_beams = static_cast<std::uint16_t>(beams);
        }
    }
    r.RejectUnknownKeys();
    if (c.ec.enabled && spec.kind != SourceKind::kUdp) {
        r.AddProblem(r.Path("ec") + ": EC steering needs a udp source");
    }
    if (c.ec.enabled && spec.kind == SourceKind::kUdp && spec.udp.reply_to.empty() &&
        spec.udp.allowed_senders.size() > 1) {
        r.AddProblem(r.Path("udp") +
                     ".reply_to: required for EC steering with more than one "
                     "allowed sender (which one is the head?)");
    }
    Append(problems, base, c.Validate());
}

LoadedConfig Load(Expected<ConfigReader> reader, const std::string& vehicle_yaml) {
    LoadedConfig out;
    if (!reader) {
        out.problems.push_back(reader.error().message);
        return out;
    }
    ConfigReader& r = *reader;
    DaemonConfig& cfg = out.config;
    std::vector<std::string> extra;
    r.Read("lcm_url", cfg.lcm_url);
    cfg.publisher.lcm_url = cfg.lcm_url;
    for (const std::string& p : ValidateLcmUrl(cfg.lcm_url)) extra.push_back(p);  // names it
    r.Read("status_period_ms", cfg.status_period_ms);
    r.Read("pps_device", cfg.pps.device);
    r.Read("pps_fetch_timeout_ms", cfg.pps.fetch_timeout_ms);
    if (!cfg.pps.device.empty()) Append(extra, r.Path("pps_device"), cfg.pps.Validate());
    // Child() only on present keys: common/config's reader over a missing key is a zombie
    // yaml-cpp node that throws on use.
    if (!r.Has("log")) r.AddProblem(r.Path("log") + ": required but missing");
    if (r.Has("log")) {
        ConfigReader l = r.Child("log");
        l.Require("directory", cfg.log.directory);
        l.Read("prefix", cfg.log.prefix);
        l.Read("rotate_bytes", cfg.log.rotate_bytes);
        l.Read("rotate_interval_s", cfg.log.rotate_interval_s);
        l.Read("flush_interval_ms", cfg.log.flush_interval_ms);
        l.Read("min_free_bytes", cfg.log.min_free_bytes);
        l.Read("resume_margin_bytes", cfg.log.resume_margin_bytes);
        l.Read("disk_check_interval_ms", cfg.log.disk_check_interval_ms);
        l.Read("queue_max_events", cfg.log.queue_max_events);
        l.Read("queue_max_bytes", cfg.log.queue_max_bytes);
        l.Read("error_retry_ms", cfg.log.error_retry_ms);
        l.Read("fallback_dir", cfg.log.fallback_directory);
        l.RejectUnknownKeys();
        Append(extra, r.Path("log"), cfg.log.Validate());
    }
    if (r.Has("publisher")) {
        ConfigReader p = r.Child("publisher");
        p.Read("queue_max_events", cfg.publisher.queue_max_events);
        p.Read("queue_max_bytes", cfg.publisher.queue_max_bytes);
        p.RejectUnknownKeys();
    }
    Append(extra, r.Path("publisher"), cfg.publisher.Validate());
    if (r.Has("clock")) {
        ConfigReader c = r.Child("clock");
        c.Read("fixed_latency_us", cfg.host_clock.fixed_latency_us);
        c.Read("sonar_header_resolution_us", cfg.sonar_clock.header_resolution_us);
        c.RejectUnknownKeys();
    }
    {
        Append(extra, r.Path("clock"), cfg.host_clock.Validate());
        Append(extra, r.Path("clock"), cfg.sonar_clock.Validate());
    }
    auto items = r.Items("channels");
    if (items.empty()) r.AddProblem(r.Path("channels") + ": at least one channel is required");
    std::set<std::string> ids;
    for (auto& item : items) {
        ChannelSpec spec;
        ReadChannel(item, spec, extra);
        if (!spec.channel.id.empty() && !ids.insert(spec.channel.id).second) {
            extra.push_back(item.Path("id") + ": duplicate channel id '" + spec.channel.id + "'");
        }
        cfg.channels.push_back(std::move(spec));
    }
    if (r.Has("vehicle")) {
        // For the processor, but checked here against its schema (common/vehicle.hpp), so a
        // wrong vehicle section stops the daemon at start, not the survey's processing later.
        ConfigReader v = r.Child("vehicle");
        VehicleDescription unused;
        ReadVehicle(v, unused);
        cfg.vehicle_yaml = vehicle_yaml;
    }
    if (cfg.status_period_ms < 100 || cfg.status_period_ms > 60'000) {
        extra.push_back(r.Path("status_period_ms") + ": must be 100..60000");
    }
    r.RejectUnknownKeys();
    out.problems = r.problems();
    out.problems.insert(out.problems.end(), extra.begin(), extra.end());
    return out;
}

// The `vehicle` section as YAML text, "" when absent or unparsable.
std::string VehicleYaml(const std::string& text) {
    try {
        const YAML::Node root = YAML::Load(text);
        if (!root.IsMap() || !root["vehicle"]) return "";
        YAML::Emitter e;
        e << root["vehicle"];
        return std::string(e.c_str()) + "\n";
    } catch (const YAML::Exception&) {
        return "";
    }
}

}  // namespace

LoadedConfig LoadDaemonConfigFromString(const std::string& yaml, const std::string& origin) {
    return Load(ConfigReader::FromString(yaml, origin), VehicleYaml(yaml));
}

LoadedConfig LoadDaemonConfig(const std::string& path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) {
        LoadedConfig out;
        out.problems.push_back(path + ": is a directory, not a config file");
        return out;
    }
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    return Load(ConfigReader::FromFile(path), VehicleYaml(ss.str()));
}

}  // namespace pitmap::acq
