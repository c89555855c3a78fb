// SPDX-License-Identifier: MIT
// The process's resident-memory high-water mark, for the per-stage figures in summary.json and
// the benchmarks.
#pragma once

#include <optional>
#include <string>

namespace pitmap {

// Peak resident set size of this process, MiB: VmHWM from /proc/self/status (which
// ResetPeakRss() can reset and which, unlike getrusage's ru_maxrss, does not carry a parent's
// peak across exec), else ru_maxrss.
double PeakRssMb();
// Resident set size of this process now, MiB (VmRSS); 0 where it cannot be read.
double ResidentMb();
// Resets the kernel's high-water mark (/proc/self/clear_refs "5", Linux >= 4.0) after handing
// the heap's free pages back (malloc_trim), so the next PeakRssMb() is the peak from now on;
// without the kernel's support the peak stays cumulative.
void ResetPeakRss();

// Large heap blocks on transparent huge pages. On a virtual machine a page fault can cost
// microseconds, and the processor's stages allocate and fill arrays of hundreds of MB (bejanca:
// `pitmap grid` spent ~15 % of its time in page faults); with 2 MB pages there are 512 times
// fewer. glibc (>= 2.35) does this when GLIBC_TUNABLES holds glibc.malloc.hugetlb=1, which it
// reads only at start-up, so ReexecWithHugePageMalloc() re-executes the program (argv as
// given, /proc/self/exe) with it set, when:
//   - the kernel's THP mode is "madvise" (with "always" malloc's blocks get them anyway, with
//     "never" there are none to have),
//   - GLIBC_TUNABLES does not already say glibc.malloc.hugetlb (the user's choice, or ours on
//     the second start), and PITMAP_HUGEPAGES is not 0 (to turn it off, e.g. under a debugger),
//   - the build is not a sanitizer build (its allocator is not glibc's),
//   - the process was not started set-user-ID (the loader drops GLIBC_TUNABLES then).
// It returns when it did not re-execute (or the exec failed): the program then runs as before.
// Call it first in main(), before any thread or output.
void ReexecWithHugePageMalloc(char** argv);
// Whether this build re-executes at all (glibc on Linux, no sanitizer).
bool HugePageRestartBuiltIn();
// The decision above without its effects: the GLIBC_TUNABLES to re-execute with, or nothing.
// thp_enabled is the text of /sys/kernel/mm/transparent_hugepage/enabled ("always [madvise]
// never"); a null pointer is an unset variable.
std::optional<std::string> HugePageTunables(const char* glibc_tunables,
                                            const char* pitmap_hugepages,
                                            const std::string& thp_enabled);
// Whether malloc's large blocks go on huge pages in a process with these GLIBC_TUNABLES and
// that THP mode: the kernel's "always", or glibc.malloc.hugetlb set to a non-zero value (1:
// transparent huge pages, 2: hugetlbfs) where THP is not "never". MallocOnHugePages() asks for
// this process (summary.json `process.malloc_huge_pages`).
bool MallocOnHugePages(const char* glibc_tunables, const std::string& thp_enabled);
bool MallocOnHugePages();

}  // namespace pitmap
