// SPDX-License-Identifier: MIT
#include "common/protocol/novatel/commands.hpp"

#include <array>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <vector>

#include "common/protocol/novatel/framer.hpp"

namespace pitmap::protocol::novatel {
namespace {

constexpr std::array<std::string_view, 6> kTriggerNames = {
    "ONNEW", "ONCHANGED", "ONTIME", "ONNEXT", "ONCE", "ONMARK"};

std::string Number(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.10g", v);
    return buf;
}

std::string WithSuffix(const std::string& message, LogFormat f) {
    if (f == LogFormat::kAscii) return message + "A";
    if (f == LogFormat::kBinary) return message + "B";
    return message;
}

void AppendPort(std::string& s, const std::string& port) {
    if (!port.empty()) s += " " + port;
}

// COM1, COM1_30, USB2, ICOM7, NCOM1, XCOM3, THISPORT, ALLPORTS.
bool IsPort(std::string_view w) {
    if (w == "THISPORT" || w == "ALLPORTS" || w == "THISPORT_ALL") return true;
    std::size_t i = 0;
    while (i < w.size() && std::isupper(static_cast<unsigned char>(w[i]))) ++i;
    const std::string_view prefix = w.substr(0, i);
    if (prefix != "COM" && prefix != "USB" && prefix != "ICOM" && prefix != "NCOM" &&
        prefix != "XCOM" && prefix != "CCOM" && prefix != "SCOM" && prefix != "AUX") {
        return false;
    }
    const std::size_t digits = i;
    while (i < w.size() && std::isdigit(static_cast<unsigned char>(w[i]))) ++i;
    if (i == digits && prefix != "AUX") return false;
    if (i == w.size()) return true;
    if (w[i] != '_' || i + 1 == w.size()) return false;
    for (++i; i < w.size(); ++i) {
        if (!std::isdigit(static_cast<unsigned char>(w[i]))) return false;
    }
    return true;
}

void SplitFormat(std::string_view name, std::string& message, LogFormat& format) {
    if (MessageIdFromName(name) || name.size() < 2 || (name.back() != 'A' && name.back() != 'B')) {
        message = std::string(name);
        format = LogFormat::kAbbreviated;
        return;
    }
    message = std::string(name.substr(0, name.size() - 1));
    format = name.back() == 'A' ? LogFormat::kAscii : LogFormat::kBinary;
}

std::optional<double> ParseNumber(std::string_view w) {
    double v = 0.0;
    const auto [p, ec] = std::from_chars(w.data(), w.data() + w.size(), v);
    if (ec != std::errc() || p != w.data() + w.size() || w.empty()) return std::nullopt;
    return v;
}

std::optional<bool> ParseOnOff(std::string_view w) {
    if (w == "ON" || w == "TRUE" || w == "ENABLE") return true;
    if (w == "OFF" || w == "FALSE" || w == "DISABLE") return false;
    return std::nullopt;
}

}  // namespace

std::string EncodeCommand(const Command& command) {
    std::string s;
    std::visit(
        [&](const auto& c) {
            using T = std::decay_t<decltype(c)>;
            if constexpr (std::is_same_v<T, LogCommand>) {
                s = "LOG";
                AppendPort(s, c.port);
                s += " " + WithSuffix(c.message, c.format);
                s += " ";
                s += kTriggerNames[static_cast<std::size_t>(c.trigger)];
                if (c.period_s) s += " " + Number(*c.period_s);
                if (c.period_s && c.offset_s) s += " " + Number(*c.offset_s);
                if (c.period_s && c.offset_s && c.hold) s += " HOLD";
            } else if constexpr (std::is_same_v<T, UnlogCommand>) {
                s = "UNLOG";
                AppendPort(s, c.port);
                s += " " + WithSuffix(c.message, c.format);
            } else if constexpr (std::is_same_v<T, UnlogAllCommand>) {
                s = "UNLOGALL";
                AppendPort(s, c.port);
                if (c.held) s += " TRUE";
            } else if constexpr (std::is_same_v<T, InterfaceModeCommand>) {
                s = "INTERFACEMODE";
                AppendPort(s, c.port);
                s += " " + c.rx_type + " " + c.tx_type;
                if (c.responses) s += *c.responses ? " ON" : " OFF";
            } else {
                s = "SERIALCONFIG";
                AppendPort(s, c.port);
                s += " " + std::to_string(c.baud);
                if (c.parity) s += std::string(" ") + *c.parity;
                if (c.parity && c.data_bits) s += " " + std::to_string(*c.data_bits);
                if (c.parity && c.data_bits && c.stop_bits) s += " " + std::to_string(*c.stop_bits);
                if (c.parity && c.data_bits && c.stop_bits && c.handshake) s += " " + *c.handshake;
                if (c.parity && c.data_bits && c.stop_bits && c.handshake && c.break_detection) {
                    s += *c.break_detection ? " ON" : " OFF";
                }
            }
        },
        command);
    return s + "\r\n";
}

std::variant<Command, CommandError> ParseCommand(std::string_view line) {
    std::string upper;
    upper.reserve(line.size());
    for (char c : line)
        upper.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(c))));
    std::vector<std::string_view> w;
    std::string_view rest(upper);
    while (!rest.empty()) {
        const std::size_t start = rest.find_first_not_of(" \t\r\n,");
        if (start == std::string_view::npos) break;
        rest = rest.substr(start);
        const std::size_t end = rest.find_first_of(" \t\r\n,");
        w.push_back(rest.substr(0, end));
        rest = end == std::string_view::npos ? std::string_view() : rest.substr(end);
    }
    if (w.empty()) return CommandError{CommandErrorKind::kEmpty, 0};
    std::size_t i = 1;
    std::string port;
    const auto take_port = [&]() {
        if (i < w.size() && IsPort(w[i])) port = std::string(w[i++]);
    };
    const auto missing = [&]() { return CommandError{CommandErrorKind::kMissingField, i}; };
    const auto bad = [&]() { return CommandError{CommandErrorKind::kBadField, i}; };
    const auto done = [&](Command c) -> std::variant<Command, CommandError> {
        if (i < w.size()) return CommandError{CommandErrorKind::kExtraField, i};
        return c;
    };

    if (w[0] == "LOG") {
        LogCommand c;
        take_port();
        c.port = port;
        if (i >= w.size()) return missing();
        SplitFormat(w[i++], c.message, c.format);
        if (i >= w.size()) {
            c.trigger = LogTrigger::kOnce;  // "LOG msg" alone is a one-shot query
            return done(c);
        }
        std::size_t t = 0;
        while (t < kTriggerNames.size() && kTriggerNames[t] != w[i]) ++t;
        if (t == kTriggerNames.size()) return bad();
        c.trigger = static_cast<LogTrigger>(t);
        ++i;
        if (i < w.size() && w[i] != "HOLD") {
            c.period_s = ParseNumber(w[i]);
            if (!c.period_s) return bad();
            ++i;
            if (i < w.size() && w[i] != "HOLD") {
                c.offset_s = ParseNumber(w[i]);
                if (!c.offset_s) return bad();
                ++i;
            }
        }
        if (i < w.size() && w[i] == "HOLD") {
            c.hold = true;
            ++i;
        }
        return done(c);
    }
    if (w[0] == "UNLOG") {
        UnlogCommand c;
        take_port();
        c.port = port;
        if (i >= w.size()) return missing();
        SplitFormat(w[i++], c.message, c.format);
        return done(c);
    }
    if (w[0] == "UNLOGALL") {
        UnlogAllCommand c;
        take_port();
        c.port = port;
        if (i < w.size()) {
            const auto held = ParseOnOff(w[i]);
            if (!held) return bad();
            c.held = *held;
            ++i;
        }
        return done(c);
    }
    if (w[0] == "INTERFACEMODE") {
        InterfaceModeCommand c;
        take_port();
        c.port = port;
        if (i + 1 >= w.size()) return missing();
        c.rx_type = std::string(w[i++]);
        c.tx_type = std::string(w[i++]);
        if (i < w.size()) {
            c.responses = ParseOnOff(w[i]);
            if (!c.responses) return bad();
            ++i;
        }
        return done(c);
    }
    if (w[0] == "SERIALCONFIG") {
        SerialConfigCommand c;
        take_port();
        c.port = port;
        if (i >= w.size()) return missing();
        std::uint32_t baud = 0;
        const auto [p, ec] = std::from_chars(w[i].data(), w[i].data() + w[i].size(), baud);
        if (ec != std::errc() || p != w[i].data() + w[i].size() || baud == 0) return bad();
        c.baud = baud;
        ++i;
        if (i < w.size()) {
            if (w[i] != "N" && w[i] != "E" && w[i] != "O") return bad();
            c.parity = w[i++][0];
        }
        for (auto* field : {&c.data_bits, &c.stop_bits}) {
            if (i >= w.size()) break;
            int v = 0;
            const auto [q, ec2] = std::from_chars(w[i].data(), w[i].data() + w[i].size(), v);
            if (ec2 != std::errc() || q != w[i].data() + w[i].size()) return bad();
            *field = v;
            ++i;
        }
        if (i < w.size()) c.handshake = std::string(w[i++]);
        if (i < w.size()) {
            c.break_detection = ParseOnOff(w[i]);
            if (!c.break_detection) return bad();
            ++i;
        }
        return done(c);
    }
    return CommandError{CommandErrorKind::kUnknownCommand, 0};
}

}  // namespace pitmap::protocol::novatel
