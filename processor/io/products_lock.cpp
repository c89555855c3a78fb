// SPDX-License-Identifier: MIT
#include "processor/io/products_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <ctime>
#include <filesystem>
#include <string>

#include "common/formats/replace_file.hpp"

namespace pitmap::proc::io {

namespace {

// What the holder wrote, on one line ("pid 123, pitmap run ..., started ..."); "" if nothing.
std::string HolderText(int fd) {
    std::string text;
    char buf[1024];
    ssize_t n = 0;
    off_t at = 0;
    while (text.size() < 4096 && (n = ::pread(fd, buf, sizeof buf, at)) > 0) {
        text.append(buf, static_cast<std::size_t>(n));
        at += n;
    }
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    std::string line;
    for (char c : text) line += c == '\n' ? std::string("; ") : std::string(1, c);
    return line;
}

std::string NowUtc() {
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    ::gmtime_r(&now, &tm);
    char b[32];
    std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return b;
}

}  // namespace

Expected<ProductsLock> ProductsLock::Acquire(const std::string& out_dir,
                                             const std::string& command,
                                             LockMode mode) {
    const bool shared = mode == LockMode::kShared;
    std::error_code ec;
    std::filesystem::create_directories(out_dir, ec);
    if (ec) return Error{out_dir + ": cannot create the products folder: " + ec.message()};
    const std::string path = out_dir + "/" + kLockFileName;
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) {
        return Error{formats::ErrnoMessage(path, "cannot create the lock file", errno) +
                     " (the products folder must be writable)"};
    }
    if (::flock(fd, (shared ? LOCK_SH : LOCK_EX) | LOCK_NB) != 0) {
        const int err = errno;
        const std::string holder = err == EWOULDBLOCK ? HolderText(fd) : "";
        ::close(fd);  // not ours: the holder's text stays
        if (err != EWOULDBLOCK) return Error{formats::ErrnoMessage(path, "cannot lock", err)};
        return Error{out_dir + " is in use by another pitmap command (" +
                     (holder.empty() ? std::string("per-tile commands (grid or fuse --tile), or "
                                                   "one that has not written its name yet")
                                     : holder) +
                     "; " + kLockFileName + "): wait for it to finish or use another --out"};
    }
    ProductsLock lock(fd, shared);
    if (shared) return lock;
    const std::string text = "pid " + std::to_string(::getpid()) + "\ncommand " + command +
                             "\nstarted " + NowUtc() + "\n";
    if (::ftruncate(fd, 0) != 0 ||
        ::pwrite(fd, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size())) {
        return Error{formats::ErrnoMessage(path, "cannot write", errno) +
                     " (the products folder must be writable)"};
    }
    return lock;
}

ProductsLock::ProductsLock(ProductsLock&& other) noexcept : fd_(other.fd_), shared_(other.shared_) {
    other.fd_ = -1;
}

ProductsLock& ProductsLock::operator=(ProductsLock&& other) noexcept {
    if (this != &other) {
        if (fd_ >= 0) ::close(fd_);
        fd_ = other.fd_;
        shared_ = other.shared_;
        other.fd_ = -1;
    }
    return *this;
}

ProductsLock::~ProductsLock() {
    if (fd_ < 0) return;
    // While still held: no one reads a finished holder's name (a shared holder wrote none).
    if (!shared_) (void)::ftruncate(fd_, 0);
    ::close(fd_);
}

}  // namespace pitmap::proc::io
