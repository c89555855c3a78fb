// SPDX-License-Identifier: MIT
// The process's resident-memory high-water mark, for the per-stage figures in summary.json and
// the benchmarks.
#pragma once

namespace pitmap {

// Peak resident set size of this process, MiB: VmHWM from /proc/self/status (which
// ResetPeakRss() can reset and which, unlike getrusage's ru_maxrss, does not carry a parent's
// peak across exec), else ru_maxrss.
double PeakRssMb();
// Resets the kernel's high-water mark (/proc/self/clear_refs "5", Linux >= 4.0) after handing
// the heap's free pages back (malloc_trim), so the next PeakRssMb() is the peak from now on;
// without the kernel's support the peak stays cumulative.
void ResetPeakRss();

}  // namespace pitmap
