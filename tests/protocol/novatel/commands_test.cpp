// SPDX-License-Identifier: MIT
// Command lines (shared/specs/novatel_oem.md §7): exact encodings and parse round trips.
#include "common/protocol/novatel/commands.hpp"

#include <gtest/gtest.h>

namespace pitmap::protocol::novatel {
namespace {

Command Parsed(std::string_view line) {
    const auto r = ParseCommand(line);
    EXPECT_TRUE(std::holds_alternative<Command>(r)) << line;
    return std::holds_alternative<Command>(r) ? std::get<Command>(r) : Command{};
}

TEST(NovatelCommands, EncodesSpecStartupScript) {
    LogCommand log{"", "INSPVAS", LogFormat::kBinary, LogTrigger::kOnTime, 0.02, {}, false};
    EXPECT_EQ(EncodeCommand(log), "LOG INSPVASB ONTIME 0.02\r\n");
    log = {"COM1", "INSPVAX", LogFormat::kBinary, LogTrigger::kOnTime, 0.05, {}, false};
    EXPECT_EQ(EncodeCommand(log), "LOG COM1 INSPVAXB ONTIME 0.05\r\n");
    log = {"ICOM1", "RAWIMUSX", LogFormat::kBinary, LogTrigger::kOnNew, {}, {}, false};
    EXPECT_EQ(EncodeCommand(log), "LOG ICOM1 RAWIMUSXB ONNEW\r\n");
    log = {"", "BESTPOS", LogFormat::kAscii, LogTrigger::kOnTime, 1.0, 0.5, true};
    EXPECT_EQ(EncodeCommand(log), "LOG BESTPOSA ONTIME 1 0.5 HOLD\r\n");
    EXPECT_EQ(EncodeCommand(UnlogAllCommand{"THISPORT", false}), "UNLOGALL THISPORT\r\n");
    EXPECT_EQ(EncodeCommand(UnlogCommand{"COM2", "BESTVEL", LogFormat::kBinary}),
              "UNLOG COM2 BESTVELB\r\n");
    EXPECT_EQ(EncodeCommand(InterfaceModeCommand{"COM1", "NOVATEL", "NOVATEL", true}),
              "INTERFACEMODE COM1 NOVATEL NOVATEL ON\r\n");
    SerialConfigCommand sc;
    sc.port = "COM1";
    sc.baud = 460800;
    sc.parity = 'N';
    sc.data_bits = 8;
    sc.stop_bits = 1;
    sc.handshake = "N";
    sc.break_detection = false;
    EXPECT_EQ(EncodeCommand(sc), "SERIALCONFIG COM1 460800 N 8 1 N OFF\r\n");
    EXPECT_EQ(Parsed("SERIALCONFIG COM1 460800 N 8 1 N OFF\r\n"), Command(sc));
}

TEST(NovatelCommands, ParsesAndRoundTrips) {
    const auto c = Parsed("log com1 inspvaxb ontime 0.05\r\n");
    ASSERT_TRUE(std::holds_alternative<LogCommand>(c));
    const auto& log = std::get<LogCommand>(c);
    EXPECT_EQ(log.port, "COM1");
    EXPECT_EQ(log.message, "INSPVAX");
    EXPECT_EQ(log.format, LogFormat::kBinary);
    EXPECT_EQ(log.trigger, LogTrigger::kOnTime);
    ASSERT_TRUE(log.period_s.has_value());
    EXPECT_DOUBLE_EQ(*log.period_s, 0.05);

    // Whole known names are not split: INSPVA abbreviated vs INSPVAA ASCII.
    EXPECT_EQ(std::get<LogCommand>(Parsed("LOG INSPVA ONCE")).format, LogFormat::kAbbreviated);
    EXPECT_EQ(std::get<LogCommand>(Parsed("LOG INSPVA ONCE")).message, "INSPVA");
    EXPECT_EQ(std::get<LogCommand>(Parsed("LOG INSPVAA ONCE")).format, LogFormat::kAscii);
    EXPECT_EQ(std::get<LogCommand>(Parsed("LOG INSPVAA ONCE")).message, "INSPVA");
    // A log name starting like a port is not a port.
    EXPECT_EQ(std::get<LogCommand>(Parsed("LOG COMCONFIGA ONCE")).port, "");
    EXPECT_EQ(std::get<LogCommand>(Parsed("LOG COM1_30 TIMEB ONTIME 1")).port, "COM1_30");

    const Command cmds[] = {
        LogCommand{"USB1", "RANGECMP", LogFormat::kBinary, LogTrigger::kOnTime, 1.0, {}, false},
        LogCommand{"", "MARK1TIME", LogFormat::kBinary, LogTrigger::kOnNew, {}, {}, false},
        LogCommand{"", "HEADING2", LogFormat::kAscii, LogTrigger::kOnNew, {}, {}, false},
        LogCommand{"COM2", "TIME", LogFormat::kBinary, LogTrigger::kOnTime, 1.0, 0.25, true},
        UnlogCommand{"", "BESTPOS", LogFormat::kBinary},
        UnlogAllCommand{"COM1", true},
        UnlogAllCommand{"", false},
        InterfaceModeCommand{"ICOM2", "NOVATEL", "NOVATELBINARY", false},
        SerialConfigCommand{"", 115200, {}, {}, {}, {}, {}},
    };
    for (const auto& cmd : cmds) EXPECT_EQ(Parsed(EncodeCommand(cmd)), cmd) << EncodeCommand(cmd);
}

TEST(NovatelCommands, RejectsBadLines) {
    EXPECT_EQ(std::get<CommandError>(ParseCommand("\r\n")).kind, CommandErrorKind::kEmpty);
    EXPECT_EQ(std::get<CommandError>(ParseCommand("FRESET")).kind,
              CommandErrorKind::kUnknownCommand);
    EXPECT_EQ(std::get<CommandError>(ParseCommand("LOG COM1")).kind,
              CommandErrorKind::kMissingField);
    const auto bad_trigger = std::get<CommandError>(ParseCommand("LOG BESTPOSB SOMETIMES"));
    EXPECT_EQ(bad_trigger.kind, CommandErrorKind::kBadField);
    EXPECT_EQ(bad_trigger.field, 2u);
    EXPECT_EQ(std::get<CommandError>(ParseCommand("LOG BESTPOSB ONTIME x")).kind,
              CommandErrorKind::kBadField);
    EXPECT_EQ(std::get<CommandError>(ParseCommand("LOG BESTPOSB ONTIME 1 2 HOLD extra")).kind,
              CommandErrorKind::kExtraField);
    EXPECT_EQ(std::get<CommandError>(ParseCommand("SERIALCONFIG COM1 fast")).kind,
              CommandErrorKind::kBadField);
}

}  // namespace
}  // namespace pitmap::protocol::novatel
