// SPDX-License-Identifier: MIT
#include "common/peak_memory.hpp"

#include <fcntl.h>
#include <malloc.h>
#include <sys/auxv.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>

namespace pitmap {

namespace {

// A "Name: N kB" line of /proc/self/status, MiB; negative when it cannot be read.
double StatusMb(const char* format) {
    long kb = -1;
    if (std::FILE* f = std::fopen("/proc/self/status", "r")) {
        char line[256];
        while (std::fgets(line, sizeof(line), f) != nullptr) {
            if (std::sscanf(line, format, &kb) == 1) break;
        }
        std::fclose(f);
    }
    return kb >= 0 ? static_cast<double>(kb) / 1024.0 : -1.0;
}

}  // namespace

double PeakRssMb() {
    if (const double mb = StatusMb("VmHWM: %ld kB"); mb >= 0) return mb;
    struct rusage u {};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_maxrss) / 1024.0;
}

double ResidentMb() {
    return std::max(0.0, StatusMb("VmRSS: %ld kB"));
}

void ResetPeakRss() {
    ::malloc_trim(0);
    const int fd = ::open("/proc/self/clear_refs", O_WRONLY | O_CLOEXEC);
    if (fd >= 0) {
        const ssize_t n = ::write(fd, "5", 1);
        (void)n;
        ::close(fd);
    }
}

std::optional<std::string> HugePageTunables(const char* glibc_tunables,
                                            const char* pitmap_hugepages,
                                            const std::string& thp_enabled) {
    if (pitmap_hugepages != nullptr && std::strcmp(pitmap_hugepages, "0") == 0) return {};
    if (thp_enabled.find("[madvise]") == std::string::npos) return {};
    const std::string current = glibc_tunables != nullptr ? glibc_tunables : "";
    if (current.find("glibc.malloc.hugetlb") != std::string::npos) return {};
    return current.empty() ? std::string("glibc.malloc.hugetlb=1")
                           : current + ":glibc.malloc.hugetlb=1";
}

namespace {

std::string ThpEnabled() {
    std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

}  // namespace

bool MallocOnHugePages(const char* glibc_tunables, const std::string& thp_enabled) {
    if (thp_enabled.find("[always]") != std::string::npos) return true;
    if (thp_enabled.find("[never]") != std::string::npos || glibc_tunables == nullptr) {
        return false;
    }
    const std::string t = glibc_tunables;
    const std::string key = "glibc.malloc.hugetlb=";
    const std::size_t at = t.rfind(key);  // the last setting wins
    if (at == std::string::npos || (at > 0 && t[at - 1] != ':')) return false;
    const std::size_t v = at + key.size();
    return v < t.size() && t[v] >= '1' && t[v] <= '9';
}

bool MallocOnHugePages() {
    return MallocOnHugePages(std::getenv("GLIBC_TUNABLES"), ThpEnabled());
}

#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define PITMAP_SANITIZED_ALLOCATOR 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define PITMAP_SANITIZED_ALLOCATOR 1
#endif
#if defined(__linux__) && defined(__GLIBC__) && !defined(PITMAP_SANITIZED_ALLOCATOR)
#define PITMAP_HUGE_PAGE_RESTART 1
#endif

bool HugePageRestartBuiltIn() {
#ifdef PITMAP_HUGE_PAGE_RESTART
    return true;
#else
    return false;
#endif
}

void ReexecWithHugePageMalloc(char** argv) {
#ifdef PITMAP_HUGE_PAGE_RESTART
    // A set-user-ID start drops GLIBC_TUNABLES at exec: it would never be seen set (a loop).
    if (::getauxval(AT_SECURE) != 0) return;
    const char* before = std::getenv("GLIBC_TUNABLES");
    const auto tunables = HugePageTunables(before, std::getenv("PITMAP_HUGEPAGES"), ThpEnabled());
    if (!tunables || argv == nullptr || argv[0] == nullptr) return;
    const std::optional<std::string> saved =
        before != nullptr ? std::optional<std::string>(before) : std::nullopt;
    if (::setenv("GLIBC_TUNABLES", tunables->c_str(), 1) != 0) return;
    ::execv("/proc/self/exe", argv);
    // No exec: carry on as we are, with the variable as it was (this process does not have
    // what it says, and what it starts should not be told it does).
    if (saved) {
        ::setenv("GLIBC_TUNABLES", saved->c_str(), 1);
    } else {
        ::unsetenv("GLIBC_TUNABLES");
    }
#else
    (void)argv;
#endif
}

}  // namespace pitmap
