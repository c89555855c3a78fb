// SPDX-License-Identifier: MIT
#include "firmware_host/io/pps_source.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <utility>

#if __has_include(<sys/timepps.h>)
#include <sys/timepps.h>
#define PITMAP_HAVE_TIMEPPS 1
#else
#define PITMAP_HAVE_TIMEPPS 0
#endif

namespace pitmap::acq {
namespace {

std::string ErrnoText(const std::string& what, int err) {
    return what + ": " + std::strerror(err) + " (errno " + std::to_string(err) + ")";
}

}  // namespace

std::vector<std::string> PpsConfig::Validate() const {
    std::vector<std::string> p;
    if (device.empty()) {
        p.push_back("pps: device path is empty");
        return p;
    }
    struct stat st {};
    if (::stat(device.c_str(), &st) != 0) {
        p.push_back(ErrnoText("pps: device " + device, errno));
    } else if (!S_ISCHR(st.st_mode)) {
        p.push_back("pps: " + device + " is not a character device");
    }
    if (fetch_timeout_ms < 1 || fetch_timeout_ms > 10'000) {
        p.push_back("pps: fetch_timeout_ms must be 1..10000");
    }
    return p;
}

bool Rfc2783Available() {
    return PITMAP_HAVE_TIMEPPS != 0;
}

Rfc2783PpsSource::Rfc2783PpsSource(std::string device) : device_(std::move(device)) {}

Rfc2783PpsSource::~Rfc2783PpsSource() {
    Close();
}

#if PITMAP_HAVE_TIMEPPS

Status Rfc2783PpsSource::Open() {
    if (fd_ >= 0) return Ok{};
    fd_ = ::open(device_.c_str(), O_RDWR | O_CLOEXEC);
    if (fd_ < 0) return Error{ErrnoText("pps: open " + device_, errno)};
    pps_handle_t h{};
    if (::time_pps_create(fd_, &h) < 0) {
        const int err = errno;
        Close();
        return Error{ErrnoText("pps: time_pps_create " + device_, err)};
    }
    handle_ = h;
    int caps = 0;
    if (::time_pps_getcap(h, &caps) < 0 || (caps & PPS_CAPTUREASSERT) == 0 ||
        (caps & PPS_CANWAIT) == 0) {
        Close();
        return Error{"pps: " + device_ + " cannot capture assert edges with a wait"};
    }
    pps_params_t params{};
    if (::time_pps_getparams(h, &params) < 0) {
        const int err = errno;
        Close();
        return Error{ErrnoText("pps: time_pps_getparams " + device_, err)};
    }
    params.mode = (params.mode & ~PPS_CAPTURECLEAR) | PPS_CAPTUREASSERT | PPS_TSFMT_TSPEC;
    if (::time_pps_setparams(h, &params) < 0) {
        const int err = errno;
        Close();
        return Error{ErrnoText("pps: time_pps_setparams " + device_, err)};
    }
    have_sequence_ = false;
    return Ok{};
}

Expected<PpsOutcome> Rfc2783PpsSource::Fetch(PpsPulse& pulse, int timeout_ms) {
    if (handle_ < 0) return Error{"pps: " + device_ + " is not open"};
    pps_info_t info{};
    timespec timeout{timeout_ms / 1000, static_cast<long>(timeout_ms % 1000) * 1'000'000};
    if (::time_pps_fetch(static_cast<pps_handle_t>(handle_), PPS_TSFMT_TSPEC, &info, &timeout) <
        0) {
        if (errno == ETIMEDOUT || errno == EINTR) return PpsOutcome::kTimeout;
        return Error{ErrnoText("pps: time_pps_fetch " + device_, errno)};
    }
    const std::uint64_t seq = info.assert_sequence;
    if (have_sequence_ && seq == last_sequence_) return PpsOutcome::kTimeout;
    have_sequence_ = true;
    last_sequence_ = seq;
    pulse.sequence = seq;
    pulse.utime_assert = static_cast<std::int64_t>(info.assert_timestamp.tv_sec) * 1'000'000 +
                         info.assert_timestamp.tv_nsec / 1000;
    return PpsOutcome::kPulse;
}

void Rfc2783PpsSource::Close() {
    if (handle_ >= 0) ::time_pps_destroy(static_cast<pps_handle_t>(handle_));
    handle_ = -1;
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
}

#else  // no <sys/timepps.h>

Status Rfc2783PpsSource::Open() {
    return Error{"pps: " + device_ +
                 ": this build has no RFC 2783 API (<sys/timepps.h>, "
                 "Debian package pps-tools)"};
}

Expected<PpsOutcome> Rfc2783PpsSource::Fetch(PpsPulse&, int) {
    return Error{"pps: no RFC 2783 API in this build"};
}

void Rfc2783PpsSource::Close() {
    fd_ = -1;
    handle_ = -1;
}

#endif

}  // namespace pitmap::acq
