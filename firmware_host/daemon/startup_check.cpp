// SPDX-License-Identifier: MIT
#include "firmware_host/daemon/startup_check.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <linux/magic.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/statfs.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <set>

namespace pitmap::acq {
namespace {

std::string ErrnoText(int err) {
    return std::strerror(err);
}

std::vector<std::string> Split(const std::string& s, char sep) {
    std::vector<std::string> out;
    std::size_t start = 0;
    for (;;) {
        const std::size_t at = s.find(sep, start);
        out.push_back(s.substr(start, at == std::string::npos ? std::string::npos : at - start));
        if (at == std::string::npos) return out;
        start = at + 1;
    }
}

bool ParseInt(const std::string& s, long long& v) {
    if (s.empty()) return false;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && p == s.data() + s.size();
}

// "host:port" with a port 1..65535; `host` gets the part before the colon.
bool HostPort(const std::string& network, std::string& host) {
    const std::size_t colon = network.rfind(':');
    if (colon == std::string::npos) return false;
    long long port = 0;
    if (!ParseInt(network.substr(colon + 1), port) || port < 1 || port > 65535) return false;
    host = network.substr(0, colon);
    return !host.empty();
}

bool IsIpv4Multicast(const std::string& host) {
    in_addr a{};
    if (::inet_pton(AF_INET, host.c_str(), &a) != 1) return false;
    const std::uint32_t v = ntohl(a.s_addr);
    return (v >> 28) == 0xE;  // 224.0.0.0/4
}

}  // namespace

std::vector<std::string> ValidateLcmUrl(const std::string& url) {
    std::vector<std::string> p;
    if (url.empty()) return p;  // log only
    const std::string what = "lcm_url '" + url + "'";
    const std::size_t sep = url.find("://");
    if (sep == std::string::npos) {
        p.push_back(what + ": not provider://[network][?options]");
        return p;
    }
    const std::string provider = url.substr(0, sep);
    std::string rest = url.substr(sep + 3);
    std::string query;
    if (const std::size_t q = rest.find('?'); q != std::string::npos) {
        query = rest.substr(q + 1);
        rest.resize(q);
    }
    const std::string& network = rest;
    static const std::set<std::string> kProviders = {"udpm", "mpudpm", "tcpq", "memq", "file"};
    if (kProviders.count(provider) == 0) {
        p.push_back(what + ": provider '" + provider +
                    "' is not one of udpm, mpudpm, tcpq, memq, file");
        return p;
    }
    std::vector<std::pair<std::string, std::string>> options;
    if (!query.empty()) {
        for (const std::string& kv : Split(query, '&')) {
            const std::size_t eq = kv.find('=');
            if (eq == std::string::npos || eq == 0 || eq + 1 == kv.size()) {
                p.push_back(what + ": option '" + kv + "' is not key=value");
                continue;
            }
            options.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
        }
    }
    auto integer_option =
        [&](const std::string& key, const std::string& value, long long lo, long long hi) {
            long long v = 0;
            if (!ParseInt(value, v) || v < lo || v > hi) {
                p.push_back(what + ": " + key + "=" + value + " is not an integer " +
                            std::to_string(lo) + ".." + std::to_string(hi));
            }
        };
    std::string host;
    if (provider == "udpm" || provider == "mpudpm") {
        // LCM 1.3 reads an empty network as garbage, not as its default group.
        if (!HostPort(network, host) || !IsIpv4Multicast(host)) {
            p.push_back(what + ": needs an IPv4 multicast group and port, e.g. " + provider +
                        "://239.255.76.67:7667");
        }
        for (const auto& [k, v] : options) {
            if (k == "ttl") {
                integer_option(k, v, 0, 255);
            } else if (k == "recv_buf_size") {
                integer_option(k, v, 1, 1LL << 31);
            } else if (provider == "mpudpm" && k == "nports") {
                integer_option(k, v, 1, 65535);
            } else {
                p.push_back(what + ": unknown " + provider + " option '" + k + "'");
            }
        }
    } else if (provider == "tcpq") {
        if (!network.empty() && !HostPort(network, host)) {
            p.push_back(what + ": tcpq needs host:port");
        }
        for (const auto& [k, v] : options) p.push_back(what + ": unknown tcpq option '" + k + "'");
    } else if (provider == "memq") {
        for (const auto& [k, v] : options) p.push_back(what + ": unknown memq option '" + k + "'");
    } else {  // file
        if (network.empty()) p.push_back(what + ": file needs a path, file:///path?mode=w");
        bool writes = false;
        for (const auto& [k, v] : options) {
            if (k == "mode") {
                if (v == "w" || v == "a") {
                    writes = true;
                } else if (v != "r") {
                    p.push_back(what + ": mode=" + v + " is not one of r, w, a");
                }
            } else if (k != "speed" && k != "start_timestamp") {
                p.push_back(what + ": unknown file option '" + k + "'");
            }
        }
        // LCM's file provider reads by default; the daemon only publishes.
        if (!writes)
            p.push_back(what + ": the daemon publishes: the file provider needs mode=w or mode=a");
    }
    return p;
}

std::vector<std::string> CheckLogDirectory(const std::string& dir) {
    std::vector<std::string> p;
    if (dir.empty()) return p;
    struct stat st {};
    if (::stat(dir.c_str(), &st) == 0 && !S_ISDIR(st.st_mode)) {
        p.push_back(dir + " is not a directory");
        return p;
    }
    // The missing components, outermost first: made for the probe and removed afterwards, so
    // a check leaves nothing behind (start-up makes them for good).
    std::vector<std::filesystem::path> missing;
    for (std::filesystem::path d = std::filesystem::path(dir).lexically_normal();
         !d.empty() && d != d.parent_path();
         d = d.parent_path()) {
        std::error_code ec;
        if (std::filesystem::exists(d, ec) || ec) break;
        missing.insert(missing.begin(), d);
    }
    std::vector<std::filesystem::path> made;
    auto undo = [&] {
        for (auto it = made.rbegin(); it != made.rend(); ++it) ::rmdir(it->c_str());
    };
    for (const auto& d : missing) {
        if (::mkdir(d.c_str(), 0750) != 0 && errno != EEXIST) {
            p.push_back("cannot create " + d.string() + ": " + ErrnoText(errno));
            undo();
            return p;
        }
        made.push_back(d);
    }
    struct statfs fs {};
    if (::statfs(dir.c_str(), &fs) == 0 &&
        (fs.f_type == PROC_SUPER_MAGIC || fs.f_type == SYSFS_MAGIC)) {
        p.push_back(dir + " is on /proc or /sys, not a disk");
        undo();
        return p;
    }
    const std::string probe = dir + "/.pitmap-acqd-check-" + std::to_string(::getpid());
    const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0640);
    if (fd < 0) {
        p.push_back("cannot create a file in " + dir + ": " + ErrnoText(errno));
    } else {
        ::close(fd);
        ::unlink(probe.c_str());
    }
    undo();
    return p;
}

namespace {

// "" when `path` opens as a terminal (isatty, which is tcgetattr), else why not. Opened
// non-blocking and without becoming the controlling terminal, and closed again at once.
std::string NotATerminal(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        // Busy or gone since the stat: the channel's own open reports it (a warning here).
        return "";
    }
    const bool tty = ::isatty(fd) == 1;
    const int err = errno;
    ::close(fd);
    if (tty) return "";
    return " is not a terminal device (" + ErrnoText(err) + "): not a serial port";
}

}  // namespace

HostCheck CheckHost(const DaemonConfig& config) {
    HostCheck out;
    for (const std::string& e : CheckLogDirectory(config.log.directory)) {
        out.errors.push_back("log.directory: " + e);
    }
    if (!config.log.fallback_directory.empty()) {
        for (const std::string& e : CheckLogDirectory(config.log.fallback_directory)) {
            out.warnings.push_back("log.fallback_dir: " + e);
        }
    }
    for (std::size_t i = 0; i < config.channels.size(); ++i) {
        const ChannelSpec& spec = config.channels[i];
        const std::string where = "channels[" + std::to_string(i) + "] (" + spec.channel.id + "): ";
        if (spec.kind == SourceKind::kSerial && !spec.serial.path.empty()) {
            const std::string& path = spec.serial.path;
            struct stat st {};
            if (::stat(path.c_str(), &st) != 0) {
                out.warnings.push_back(where + "serial device " + path + ": " + ErrnoText(errno) +
                                       " (the channel retries until it "
                                       "appears)");
            } else if (!S_ISCHR(st.st_mode)) {
                out.errors.push_back(where + "serial device " + path +
                                     " is not a character device (not a serial port)");
            } else if (::access(path.c_str(), R_OK | W_OK) != 0) {
                out.warnings.push_back(where + "serial device " + path + ": " + ErrnoText(errno) +
                                       " (is this user in its group?)");
            } else if (const std::string tty = NotATerminal(path); !tty.empty()) {
                // /dev/null, /dev/zero: character devices that are no serial port. The channel
                // would open them, read nothing or junk and retry for ever.
                out.errors.push_back(where + "serial device " + path + tty);
            }
        }
        if (spec.kind == SourceKind::kUdp && spec.udp.port > 0) {
            const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
            sockaddr_in a{};
            a.sin_family = AF_INET;
            a.sin_port = htons(static_cast<std::uint16_t>(spec.udp.port));
            if (fd >= 0 && ::inet_pton(AF_INET, spec.udp.bind_address.c_str(), &a.sin_addr) == 1 &&
                ::bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof(a)) != 0) {
                out.warnings.push_back(where + "UDP " + spec.udp.bind_address + ":" +
                                       std::to_string(spec.udp.port) + ": " + ErrnoText(errno) +
                                       (errno == EADDRINUSE ? " (another program has it; the "
                                                              "channel retries)"
                                                            : ""));
            }
            if (fd >= 0) ::close(fd);
        }
    }
    return out;
}

}  // namespace pitmap::acq
