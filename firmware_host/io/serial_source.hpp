// SPDX-License-Identifier: MIT
// SerialSource: an RS-232/USB serial port through POSIX termios, in raw mode.
//
// Raw means every byte passes unchanged both ways: cfmakeraw (no echo, no ICANON, no ISIG, no
// IXON/IXOFF, no CR/NL mapping, no output processing), CLOCAL|CREAD, 8N1, received breaks
// ignored (IGNBRK). A cooked tty echoes receiver output back as commands and turns \r into \n;
// a real capture shows a terminal reply leaking into the stream that way (NovAtel spec §7).
// This class never sends a break (a break resets a NovAtel port to factory defaults).
//
// Exclusive use: TIOCEXCL plus flock(LOCK_EX|LOCK_NB), so a second daemon or a terminal
// program cannot steal bytes (TIOCEXCL alone does not stop root). Open the stable path
// (/dev/serial/by-id/...): when the adapter is unplugged, reads fail (EIO/ENXIO/ENODEV or end
// of stream) and the source reopens the same path with backoff until it comes back.
//
// THREADING: as ByteSource (one owner thread).
#pragma once

#include <string>
#include <vector>

#include "firmware_host/io/detail/stream_source.hpp"

namespace pitmap::acq {

struct SerialConfig {
    std::string path;                      // device path, e.g. /dev/serial/by-id/usb-FTDI_...-port0
    int baud = 115200;                     // line rate, bit/s; one of SupportedBaudRates()
    bool rtscts = false;                   // hardware flow control (CRTSCTS)
    bool exclusive = true;                 // TIOCEXCL + flock; off only for tests on shared ttys
    std::size_t read_buffer_bytes = 4096;  // largest chunk one Read() returns, bytes
    BackoffConfig reopen_backoff{};        // reopen delays after a loss

    // Every problem, empty when valid.
    std::vector<std::string> Validate() const;
};

// The rates this build can set (termios Bxxx constants), ascending, up to 921600.
std::vector<int> SupportedBaudRates();

class SerialSource final : public detail::StreamSource {
public:
    // Precondition: config.Validate() is empty.
    explicit SerialSource(SerialConfig config);

    Transport transport() const override { return Transport::kSerial; }
    std::string description() const override;

protected:
    Expected<detail::UniqueFd> OpenFd() override;
    long ReadSome(int fd,
                  std::byte* dst,
                  std::size_t capacity,
                  std::int64_t& utime_kernel) override;
    long WriteSome(int fd, const std::byte* src, std::size_t size) override;
    std::string peer() const override { return config_.path; }

private:
    SerialConfig config_;
};

}  // namespace pitmap::acq
