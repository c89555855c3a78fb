// SPDX-License-Identifier: MIT
// NovAtel receiver commands as abbreviated ASCII lines (shared/specs/novatel_oem.md §7; OEM7
// manual Commands/LOG, UNLOG, UNLOGALL, INTERFACEMODE, SERIALCONFIG): an encoder for the daemon
// and a parser for the receiver emulator. Lines end CR LF; parsing is case insensitive and
// accepts a bare LF or no terminator.
//
// Message names carry the format suffix: "BESTPOSB" binary, "BESTPOSA" ASCII, "BESTPOS"
// abbreviated. A name the id table (MessageIdFromName) knows as a whole wins over stripping a
// suffix ("INSPVA" is INSPVA abbreviated, "INSPVAA" INSPVA ASCII); an unknown name ending in
// A or B is taken as suffixed.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>

namespace pitmap::protocol::novatel {

enum class LogFormat : std::uint8_t { kAbbreviated = 0, kAscii, kBinary };
enum class LogTrigger : std::uint8_t { kOnNew = 0, kOnChanged, kOnTime, kOnNext, kOnce, kOnMark };

struct LogCommand {
    std::string port;     // "" = THISPORT (omitted)
    std::string message;  // without suffix, e.g. "INSPVAS"
    LogFormat format = LogFormat::kBinary;
    LogTrigger trigger = LogTrigger::kOnNew;
    std::optional<double> period_s;
    std::optional<double> offset_s;
    bool hold = false;
    bool operator==(const LogCommand&) const = default;
};

struct UnlogCommand {
    std::string port;
    std::string message;
    LogFormat format = LogFormat::kBinary;
    bool operator==(const UnlogCommand&) const = default;
};

struct UnlogAllCommand {
    std::string port;
    bool held = false;  // "TRUE": also remove logs with HOLD
    bool operator==(const UnlogAllCommand&) const = default;
};

struct InterfaceModeCommand {
    std::string port;
    std::string rx_type;  // e.g. "NOVATEL"
    std::string tx_type;
    std::optional<bool> responses;  // ON/OFF
    bool operator==(const InterfaceModeCommand&) const = default;
};

struct SerialConfigCommand {
    std::string port;
    std::uint32_t baud = 9600;
    std::optional<char> parity;  // 'N', 'E', 'O'
    std::optional<int> data_bits;
    std::optional<int> stop_bits;
    std::optional<std::string> handshake;  // "N", "XON", "CTS"
    std::optional<bool> break_detection;   // ON/OFF
    bool operator==(const SerialConfigCommand&) const = default;
};

using Command = std::
    variant<LogCommand, UnlogCommand, UnlogAllCommand, InterfaceModeCommand, SerialConfigCommand>;

enum class CommandErrorKind : std::uint8_t {
    kEmpty = 0,
    kUnknownCommand,
    kMissingField,
    kBadField,
    kExtraField,
};

struct CommandError {
    CommandErrorKind kind = CommandErrorKind::kEmpty;
    std::size_t field = 0;  // index of the offending word (0 = command name)
    bool operator==(const CommandError&) const = default;
};

// The command as one abbreviated ASCII line ending CR LF, e.g. "LOG COM1 BESTPOSB ONTIME 1\r\n".
std::string EncodeCommand(const Command& command);
// Parses one command line (terminator optional).
std::variant<Command, CommandError> ParseCommand(std::string_view line);

}  // namespace pitmap::protocol::novatel
