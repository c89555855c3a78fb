// SPDX-License-Identifier: MIT
#include "processor/edit/edit_command.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include "common/config.hpp"

extern char** environ;

namespace pitmap::proc::edit {

namespace {

void Say(const std::string& m) {
    std::fprintf(stderr, "pitmap edit: %s\n", m.c_str());
}

// xdg-open URL, not waited for beyond its own start (it returns once the browser is asked).
void OpenBrowser(const std::string& url) {
    std::string xdg = "xdg-open";
    char* argv[] = {xdg.data(), const_cast<char*>(url.c_str()), nullptr};
    pid_t pid = -1;
    if (::posix_spawnp(&pid, "xdg-open", nullptr, nullptr, argv, environ) != 0) {
        Say("no xdg-open here: open the URL above in a browser");
        return;
    }
    std::thread([pid] {
        int st = 0;
        ::waitpid(pid, &st, 0);
    }).detach();
}

}  // namespace

int RunEditCommand(const EditCommand& command, const std::function<bool()>& stop) {
    auto problems = command.session.Validate();
    for (auto& p : command.server.Validate()) problems.push_back(std::move(p));
    if (!problems.empty()) {
        Say("invalid config:\n" + FormatProblems(problems));
        return 1;
    }
    Say("loading " + command.out_dir + " ...");
    const auto t0 = std::chrono::steady_clock::now();
    auto session = EditSession::Open(command.out_dir, command.session);
    if (!session) {
        Say(session.error().message);
        return 1;
    }
    Say((*session)->description() + " (" +
        std::to_string(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()) +
        " s)");
    EditServerConfig sc = command.server;
    sc.out_dir = command.out_dir;
    EditServer server(**session, sc);
    if (auto st = server.Start(); !st) {
        Say(st.error().message);
        return 1;
    }
    std::printf("%s\n", server.url().c_str());
    std::fflush(stdout);
    if (command.open_browser) OpenBrowser(server.url());
    while (!stop()) std::this_thread::sleep_for(std::chrono::milliseconds(200));
    server.Stop();
    return 0;
}

}  // namespace pitmap::proc::edit
