// SPDX-License-Identifier: MIT
#include "common/peak_memory.hpp"

#include <fcntl.h>
#include <malloc.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>

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

}  // namespace pitmap
