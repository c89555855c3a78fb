// SPDX-License-Identifier: MIT
// pitmap-inspect: frame counts, CRC failures, skipped bytes and time span of a raw NovAtel file,
// a .83P file, a pcap/pcapng(.gz) capture or a pitmap LCM log. See inspect.hpp.
// Exit (common/exit_codes.hpp): 0 ok, 1 the file unreadable, 2 usage, 3 internal error.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>
#include <iostream>
#include <string>

#include "common/cli/parse.hpp"
#include "common/exit_codes.hpp"
#include "tools/inspect/inspect.hpp"

int main(int argc, char** argv) {
    namespace inspect = pitmap::tools::inspect;
    CLI::App app{"pitmap-inspect: what is in a sensor byte file, capture or LCM log"};
    std::string path;
    std::string format = "auto";
    std::string protocol = "auto";
    bool json = false;
    std::size_t dump_first = 0;
    app.add_option("file",
                   path,
                   "input: NovAtel raw (.gps/.GPS/.ASC/.dat), .83P, "
                   ".pcap/.pcapng[.gz] or LCM log")
        ->required();
    app.add_option("--format", format, "input kind: auto, raw, 83p, pcap, lcm")
        ->capture_default_str();
    app.add_option("--protocol", protocol, "framing of raw bytes: auto, novatel, deltat")
        ->capture_default_str();
    app.add_flag("--json", json, "print one JSON object instead of text");
    app.add_option("--dump-first",
                   dump_first,
                   "decoded fields of the first N (and the last) BESTPOS, BESTVEL, INSPVA(S), "
                   "INSPVAX, INSATTX, HEADING2 and TIME messages");
    if (auto code = pitmap::cli::ParseCommandLine(app, argc, argv, "pitmap-inspect")) return *code;
    namespace codes = pitmap::exit_code;

    try {
        inspect::InspectOptions options;
        const auto parsed_format = inspect::ParseInputFormat(format);
        const auto parsed_protocol = inspect::ParseProtocol(protocol);
        if (!parsed_format || !parsed_protocol) {
            std::cerr << "pitmap-inspect: unknown "
                      << (!parsed_format ? "--format " + format : "--protocol " + protocol) << "\n";
            return codes::kUsage;
        }
        options.format = *parsed_format;
        options.protocol = *parsed_protocol;
        options.dump_first = dump_first;
        if (format == "83p" && options.protocol == inspect::Protocol::kAuto) {
            options.protocol = inspect::Protocol::kDeltaT;
        }
        const auto report = inspect::InspectFile(path, options);
        if (!report) {
            std::cerr << "pitmap-inspect: " << report.error().message << "\n";
            return codes::kFailure;
        }
        if (json) {
            std::cout << inspect::ToJson(*report).dump(2) << "\n";
        } else {
            std::cout << inspect::ToText(*report);
        }
        return codes::kOk;
    } catch (const std::exception& e) {
        std::cerr << "pitmap-inspect: internal error: " << path << ": " << e.what() << "\n";
        return codes::kInternal;
    }
}
