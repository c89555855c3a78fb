// SPDX-License-Identifier: MIT
// One command at a time on a products folder P: every stage command (pitmap georef, calibrate,
// slam, grid, fuse, mesh, report, run) holds an exclusive flock(2) on P/.pitmap.lock for its
// whole run. The kernel releases it when the holder exits or is killed (kill -9 too), so a lock
// is never left behind. The holder writes its pid, command line and start time into the file,
// and a second command on P fails at once naming them (no waiting). The per-tile commands take
// it shared instead (LockMode::kShared): they run side by side, and exclude the others.
//
// Taking the lock is also the check that P can be written: the folder is created (mkdir -p) and
// the lock file opened for writing before any work, so a read-only or impossible P fails before
// ingest with the path and the system's reason.
#pragma once

#include <string>

#include "common/result.hpp"

namespace pitmap::proc::io {

inline constexpr const char* kLockFileName = ".pitmap.lock";

// kShared: the per-tile commands (grid --tile, fuse --tile), which only read P's survey and each
// write their own tile's files, run side by side (a campaign's tile jobs), and exclude every
// other command; they do not write their names into the file.
enum class LockMode { kExclusive, kShared };

class ProductsLock {
public:
    // Creates `out_dir` and takes the lock without waiting. `command` is what the file records
    // as the holder's command (e.g. the command line). Errors: the folder or the lock file cannot
    // be created or written (path and reason), or the lock is held ("P is in use by pid N
    // (COMMAND, started TIME)").
    static Expected<ProductsLock> Acquire(const std::string& out_dir,
                                          const std::string& command,
                                          LockMode mode = LockMode::kExclusive);

    ProductsLock(ProductsLock&& other) noexcept;
    ProductsLock& operator=(ProductsLock&& other) noexcept;
    ProductsLock(const ProductsLock&) = delete;
    ProductsLock& operator=(const ProductsLock&) = delete;
    // Empties the file and releases the lock.
    ~ProductsLock();

private:
    ProductsLock(int fd, bool shared) : fd_(fd), shared_(shared) {}
    int fd_ = -1;
    bool shared_ = false;
};

}  // namespace pitmap::proc::io
