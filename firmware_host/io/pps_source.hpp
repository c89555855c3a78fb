// SPDX-License-Identifier: MIT
// PpsSource: pulse-per-second assert timestamps from the kernel through the RFC 2783 API
// (<sys/timepps.h>, Debian package pps-tools; the kernel's /dev/ppsN from pps-gpio, pps-ldisc
// on a serial DCD line, ...). Each pulse marks a whole GPS second; the daemon labels it with
// its host clock model (HostClockModel::AddPps).
//
// Rfc2783PpsSource is deliberately small: open the device, time_pps_create, ask for assert
// captures as timespecs, then time_pps_fetch with a timeout per call. It has been built and
// exercised only against the API's error paths here; no PPS device was available, so the
// behaviour with a real /dev/ppsN is untested on hardware. Where the header is missing at
// build time, Open() fails with a message saying so.
//
// THREADING: a source is owned by one thread (the daemon's PPS thread).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/result.hpp"

namespace pitmap::acq {

struct PpsConfig {
    std::string device;           // PPS device, e.g. /dev/pps0; "" = no PPS
    int fetch_timeout_ms = 1500;  // one time_pps_fetch wait, milliseconds (1..10000)

    // Every problem, empty when valid. Checks that the device exists and is a character
    // device, so a wrong path is reported at start-up.
    std::vector<std::string> Validate() const;
};

// One pulse: the kernel's assert timestamp (CLOCK_REALTIME), Unix microseconds.
struct PpsPulse {
    std::int64_t utime_assert = 0;
    std::uint64_t sequence = 0;  // the kernel's assert sequence number
};

enum class PpsOutcome { kPulse, kTimeout };

class PpsSource {
public:
    virtual ~PpsSource() = default;
    PpsSource() = default;
    PpsSource(const PpsSource&) = delete;
    PpsSource& operator=(const PpsSource&) = delete;

    virtual Status Open() = 0;
    // Waits at most timeout_ms for a pulse newer than the last one returned. An error means
    // the device failed; the caller closes and reopens it later.
    virtual Expected<PpsOutcome> Fetch(PpsPulse& pulse, int timeout_ms) = 0;
    virtual void Close() = 0;
    virtual std::string description() const = 0;
};

// True when this build has <sys/timepps.h>.
bool Rfc2783Available();

class Rfc2783PpsSource final : public PpsSource {
public:
    explicit Rfc2783PpsSource(std::string device);
    ~Rfc2783PpsSource() override;

    Status Open() override;
    Expected<PpsOutcome> Fetch(PpsPulse& pulse, int timeout_ms) override;
    void Close() override;
    std::string description() const override { return "pps " + device_; }

private:
    std::string device_;
    int fd_ = -1;
    long handle_ = -1;  // pps_handle_t is an int in the Linux implementation
    [[maybe_unused]] std::uint64_t last_sequence_ = 0;  // unused without <sys/timepps.h>
    [[maybe_unused]] bool have_sequence_ = false;
};

}  // namespace pitmap::acq
