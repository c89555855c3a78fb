// SPDX-License-Identifier: MIT
#include "common/cli/parse.hpp"

#include <cstdio>
#include <cstdlib>

#include "common/cli/suggest.hpp"
#include "common/exit_codes.hpp"
#include "common/version.hpp"

namespace pitmap::cli {

namespace {

const CLI::App* FindSubcommand(const CLI::App& app, const std::string& name) {
    for (const CLI::App* s : app.get_subcommands([](const CLI::App*) { return true; })) {
        if (s->get_name() == name) return s;
    }
    return nullptr;
}

std::vector<std::string> SubcommandNames(const CLI::App& app) {
    std::vector<std::string> out;
    for (const CLI::App* s : app.get_subcommands([](const CLI::App*) { return true; })) {
        if (!s->get_name().empty()) out.push_back(s->get_name());
    }
    return out;
}

// The option `name` ("--out", "-h") names in `app` or a parent; nullptr when none.
const CLI::Option* FindOption(const CLI::App& app, const std::string& name) {
    for (const CLI::App* a = &app; a; a = a->get_parent()) {
        for (const CLI::Option* o : a->get_options()) {
            const auto& names = name.rfind("--", 0) == 0 ? o->get_lnames() : o->get_snames();
            const std::string bare = name.substr(name.rfind("--", 0) == 0 ? 2 : 1);
            for (const auto& n : names) {
                if (n == bare) return o;
            }
        }
    }
    return nullptr;
}

std::vector<std::string> OptionNames(const CLI::App& app, bool long_names) {
    std::vector<std::string> out;
    for (const CLI::App* a = &app; a; a = a->get_parent()) {
        for (const CLI::Option* o : a->get_options()) {
            if (long_names) {
                for (const auto& n : o->get_lnames()) out.push_back("--" + n);
            } else {
                for (const auto& n : o->get_snames()) out.push_back("-" + n);
            }
        }
    }
    return out;
}

// A negative number ("-2", "-0.5") is a value, not an option.
bool IsNumber(const std::string& s) {
    if (s.empty()) return false;
    char* end = nullptr;
    std::strtod(s.c_str(), &end);
    return end != s.c_str() && *end == '\0';
}

// "pitmap run": the program and the commands the arguments chose (for the --help hint).
std::string CommandPath(const CLI::App& app,
                        const std::vector<std::string>& args,
                        std::string_view program) {
    std::string path(program);
    const CLI::App* active = &app;
    for (const std::string& arg : args) {
        if (arg.empty() || arg[0] == '-') continue;
        if (const CLI::App* sub = FindSubcommand(*active, arg)) {
            path += " " + sub->get_name();
            active = sub;
        }
    }
    return path;
}

std::string Where(const CLI::App& app) {
    return app.get_parent() ? " for '" + app.get_name() + "'" : "";
}

}  // namespace

std::string UnknownNameMessage(const CLI::App& app, const std::vector<std::string>& args) {
    const CLI::App* active = &app;
    const CLI::Option* wants_value = nullptr;  // the previous option takes a value
    for (const std::string& arg : args) {
        if (arg == "--") break;
        if (arg.size() > 1 && arg[0] == '-' && !IsNumber(arg)) {
            wants_value = nullptr;
            const bool is_long = arg.rfind("--", 0) == 0;
            // "--out=P" names --out; "-j4" names -j.
            const std::string name = is_long ? arg.substr(0, arg.find('=')) : arg.substr(0, 2);
            const CLI::Option* o = FindOption(*active, name);
            if (!o) {
                std::vector<std::string> candidates = OptionNames(*active, true);
                if (!is_long) {
                    for (auto& s : OptionNames(*active, false)) candidates.push_back(s);
                    // "-out": a long option with one dash.
                    if (arg.size() > 2) {
                        const std::string as_long = "-" + arg.substr(0, arg.find('='));
                        if (FindOption(*active, as_long)) {
                            return "unknown option '" + arg + "'" + Where(*active) +
                                   "; did you mean '" + as_long + "'?";
                        }
                    }
                }
                return "unknown option '" + name + "'" + Where(*active) +
                       DidYouMean(name, candidates);
            }
            const bool has_inline_value =
                is_long ? arg.find('=') != std::string::npos : arg.size() > 2;
            if (o->get_type_size() != 0 && !has_inline_value) wants_value = o;
            continue;
        }
        if (wants_value) {
            // A value of the previous option; a vector option may take more (CLI11 decides).
            if (wants_value->get_items_expected_max() <= 1) wants_value = nullptr;
            continue;
        }
        if (const CLI::App* sub = FindSubcommand(*active, arg)) {
            active = sub;
            continue;
        }
        // A command is expected here when the top level has commands and none is chosen yet.
        if (active == &app && !SubcommandNames(app).empty()) {
            return "unknown command '" + arg + "'" + DidYouMean(arg, SubcommandNames(app));
        }
    }
    return "";
}

std::optional<int> ParseCommandLine(CLI::App& app,
                                    int argc,
                                    char** argv,
                                    std::string_view program) {
    app.set_version_flag("--version", VersionLine(program), "print the version and git commit");
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // --help, --help-all and --version are "errors" with exit code 0: CLI11 prints them.
        if (e.get_exit_code() == 0) {
            app.exit(e);
            return exit_code::kOk;
        }
        std::vector<std::string> args;
        for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
        const std::string unknown = UnknownNameMessage(app, args);
        const std::string p(program);
        std::fprintf(stderr, "%s: %s\n", p.c_str(), unknown.empty() ? e.what() : unknown.c_str());
        std::fprintf(stderr,
                     "Run '%s --help' for the commands and options.\n",
                     CommandPath(app, args, program).c_str());
        return exit_code::kUsage;
    }
    return std::nullopt;
}

}  // namespace pitmap::cli
