// SPDX-License-Identifier: MIT
#include "firmware_host/io/serial_source.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <utility>

#include "common/result.hpp"

namespace pitmap::acq {
namespace {

struct BaudEntry {
    int rate;
    speed_t code;
};

constexpr BaudEntry kBauds[] = {
    {1200, B1200},
    {2400, B2400},
    {4800, B4800},
    {9600, B9600},
    {19200, B19200},
    {38400, B38400},
    {57600, B57600},
    {115200, B115200},
    {230400, B230400},
    {460800, B460800},
    {500000, B500000},
    {576000, B576000},
    {921600, B921600},
};

bool BaudCode(int rate, speed_t& code) {
    for (const auto& e : kBauds) {
        if (e.rate == rate) {
            code = e.code;
            return true;
        }
    }
    return false;
}

}  // namespace

std::vector<int> SupportedBaudRates() {
    std::vector<int> v;
    for (const auto& e : kBauds) v.push_back(e.rate);
    return v;
}

std::vector<std::string> SerialConfig::Validate() const {
    std::vector<std::string> problems;
    if (path.empty()) problems.push_back("serial: path is empty");
    speed_t code{};
    if (!BaudCode(baud, code)) {
        std::string list;
        for (int r : SupportedBaudRates()) list += (list.empty() ? "" : ", ") + std::to_string(r);
        problems.push_back("serial: baud " + std::to_string(baud) +
                           " is not supported (use one of " + list + ")");
    }
    if (read_buffer_bytes == 0) problems.push_back("serial: read_buffer_bytes must be > 0");
    if (reopen_backoff.initial_ms <= 0 || reopen_backoff.max_ms < reopen_backoff.initial_ms ||
        reopen_backoff.factor < 1.0) {
        problems.push_back("serial: reopen_backoff needs 0 < initial_ms <= max_ms, factor >= 1");
    }
    return problems;
}

SerialSource::SerialSource(SerialConfig config)
    : StreamSource(config.reopen_backoff, config.read_buffer_bytes), config_(std::move(config)) {
    PITMAP_CHECK(config_.Validate().empty(), "SerialSource: invalid config");
}

std::string SerialSource::description() const {
    return "serial " + config_.path + " " + std::to_string(config_.baud) + " 8N1" +
           (config_.rtscts ? " rtscts" : "");
}

Expected<detail::UniqueFd> SerialSource::OpenFd() {
    const std::string& p = config_.path;
    // O_NONBLOCK: open must not wait for carrier; reads are gated by poll anyway.
    detail::UniqueFd fd(::open(p.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
    if (!fd.valid()) return Error{detail::ErrnoMessage("serial: open " + p, errno)};
    if (!::isatty(fd.get())) return Error{"serial: " + p + " is not a terminal device"};
    if (config_.exclusive) {
        if (::flock(fd.get(), LOCK_EX | LOCK_NB) != 0) {
            return Error{detail::ErrnoMessage("serial: " + p + " is in use (flock)", errno)};
        }
        if (::ioctl(fd.get(), TIOCEXCL) != 0) {
            return Error{detail::ErrnoMessage("serial: TIOCEXCL on " + p, errno)};
        }
    }
    termios tio{};
    if (::tcgetattr(fd.get(), &tio) != 0) {
        return Error{detail::ErrnoMessage("serial: tcgetattr " + p, errno)};
    }
    ::cfmakeraw(&tio);
    // cfmakeraw already clears most of these; spelled out so a reader sees every choice.
    tio.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY | ICRNL | INLCR | IGNCR | ISTRIP |
                                          BRKINT | PARMRK | INPCK);
    tio.c_iflag |= IGNBRK;
    tio.c_oflag &= ~static_cast<tcflag_t>(OPOST | ONLCR | OCRNL);
    tio.c_lflag &= ~static_cast<tcflag_t>(ECHO | ECHONL | ECHOE | ICANON | ISIG | IEXTEN);
    tio.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | CSTOPB | CRTSCTS);
    tio.c_cflag |= CS8 | CLOCAL | CREAD;
    if (config_.rtscts) tio.c_cflag |= CRTSCTS;
    // With O_NONBLOCK, VMIN=1 makes an empty read fail with EAGAIN instead of returning 0, so
    // 0 always means end of stream (hangup). poll() does the waiting.
    tio.c_cc[VMIN] = 1;
    tio.c_cc[VTIME] = 0;
    speed_t code{};
    BaudCode(config_.baud, code);
    if (::cfsetispeed(&tio, code) != 0 || ::cfsetospeed(&tio, code) != 0) {
        return Error{detail::ErrnoMessage("serial: cfsetspeed " + p, errno)};
    }
    if (::tcsetattr(fd.get(), TCSANOW, &tio) != 0) {
        return Error{detail::ErrnoMessage("serial: tcsetattr " + p, errno)};
    }
    // tcsetattr succeeds if any one change took; read back to be sure the port is raw.
    termios check{};
    if (::tcgetattr(fd.get(), &check) != 0) {
        return Error{detail::ErrnoMessage("serial: tcgetattr " + p, errno)};
    }
    if (::cfgetispeed(&check) != code || (check.c_lflag & (ICANON | ECHO | ISIG)) != 0 ||
        (check.c_cflag & CSIZE) != CS8) {
        return Error{"serial: " + p + " did not accept raw 8N1 at " + std::to_string(config_.baud)};
    }
    return fd;
}

long SerialSource::ReadSome(int fd, std::byte* dst, std::size_t capacity, std::int64_t&) {
    const long n = ::read(fd, dst, capacity);
    // A pty slave whose master closed, or an unplugged USB adapter, reports EIO/ENXIO/ENODEV
    // (or end of stream); the base class treats any failure other than EAGAIN as a loss.
    return n;
}

long SerialSource::WriteSome(int fd, const std::byte* src, std::size_t size) {
    return ::write(fd, src, size);
}

}  // namespace pitmap::acq
