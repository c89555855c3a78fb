// SPDX-License-Identifier: MIT
#include "processor/pipeline/report_program.hpp"

#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

extern char** environ;

namespace pitmap::proc::pipeline {

Expected<ReportRun> RunReportProgram(const std::string& program,
                                     const std::vector<std::string>& args,
                                     const std::string& what_without) {
    if (program.empty() || ::access(program.c_str(), X_OK) != 0) {
        return Error{"report: the report program " +
                     (program.empty() ? std::string("(pitmap-report)") : program) +
                     " is not there; " + what_without};
    }
    std::vector<std::string> all = {program};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    // fork + exec rather than posix_spawn: the child asks the kernel for SIGTERM when this
    // process dies (PR_SET_PDEATHSIG, kept across exec), so a pitmap killed with -9 during the
    // report takes pitmap-report (and through it its workers) along instead of leaving them
    // running. The child also starts with SIGTERM unblocked and at its default action, whatever
    // this process inherited (a blocked or ignored SIGTERM passes through exec). Between fork
    // and exec only async-signal-safe calls.
    const pid_t parent = ::getpid();
    const pid_t pid = ::fork();
    if (pid < 0) return Error{"report: cannot start " + program + ": " + std::strerror(errno)};
    if (pid == 0) {
        sigset_t none;
        ::sigemptyset(&none);
        ::sigprocmask(SIG_SETMASK, &none, nullptr);
        struct sigaction dfl {};
        dfl.sa_handler = SIG_DFL;
        ::sigaction(SIGTERM, &dfl, nullptr);
        ::sigaction(SIGINT, &dfl, nullptr);
        ::prctl(PR_SET_PDEATHSIG, SIGTERM);
        if (::getppid() != parent) ::_exit(127);  // the parent died before the prctl
        ::execve(program.c_str(), argv.data(), environ);
        ::_exit(127);
    }
    int status = 0;
    struct rusage usage {};
    while (::wait4(pid, &status, 0, &usage) < 0) {
        if (errno != EINTR) return Error{"report: lost " + program};
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        return Error{"report: " + program + " failed (exit status " +
                     std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")"};
    }
    ReportRun r;
    // The work is the child's: its own high-water mark (ru_maxrss, kB).
    r.peak_rss_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;
    r.cpu_seconds = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                    (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) * 1e-6;
    return r;
}

}  // namespace pitmap::proc::pipeline
