// SPDX-License-Identifier: MIT
#include "common/peak_memory.hpp"

#include <fcntl.h>
#include <malloc.h>
#include <sys/auxv.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>

namespace pitmap {

double PeakRssMb() {
    if (std::FILE* f = std::fopen("/proc/self/status", "r")) {
        char line[256];
        long kb = -1;
        while (std::fgets(line, sizeof(line), f) != nullptr) {
            if (std::sscanf(line, "VmHWM: %ld kB", &kb) == 1) break;
        }
        std::fclose(f);
        if (kb >= 0) return static_cast<double>(kb) / 1024.0;
    }
    struct rusage u {};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_maxrss) / 1024.0;
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

void ReexecWithHugePageMalloc(char** argv) {
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
    // A set-user-ID start drops GLIBC_TUNABLES at exec: it would never be seen set (a loop).
    if (::getauxval(AT_SECURE) != 0) return;
    std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
    const std::string thp((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    const auto tunables =
        HugePageTunables(std::getenv("GLIBC_TUNABLES"), std::getenv("PITMAP_HUGEPAGES"), thp);
    if (!tunables || argv == nullptr || argv[0] == nullptr) return;
    if (::setenv("GLIBC_TUNABLES", tunables->c_str(), 1) != 0) return;
    ::execv("/proc/self/exe", argv);
    // No exec: carry on as we are (the variable stays set, for programs started from here).
#else
    (void)argv;
#endif
}

}  // namespace pitmap
