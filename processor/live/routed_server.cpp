// SPDX-License-Identifier: MIT
#include "processor/live/routed_server.hpp"

#include <sys/random.h>

#include <algorithm>
#include <cctype>
#include <cerrno>

#include "common/result.hpp"

namespace pitmap::proc::live {

namespace {

// One complete request (from HttpFront) in, httplib's answer out.
class BufferStream : public httplib::Stream {
public:
    explicit BufferStream(const FrontRequest& r) : r_(r) {}
    bool is_readable() const override { return true; }
    bool is_writable() const override { return true; }
    ssize_t read(char* ptr, size_t size) override {
        const std::size_t n = std::min(size, r_.bytes.size() - pos_);
        std::copy_n(r_.bytes.data() + pos_, n, ptr);
        pos_ += n;
        return static_cast<ssize_t>(n);
    }
    ssize_t write(const char* ptr, size_t size) override {
        out_.append(ptr, size);
        return static_cast<ssize_t>(size);
    }
    void get_remote_ip_and_port(std::string& ip, int& port) const override {
        ip = r_.peer_ip;
        port = r_.peer_port;
    }
    void get_local_ip_and_port(std::string& ip, int& port) const override {
        ip.clear();
        port = 0;
    }
    socket_t socket() const override { return INVALID_SOCKET; }
    std::string& out() { return out_; }

private:
    const FrontRequest& r_;
    std::size_t pos_ = 0;
    std::string out_;
};

}  // namespace

// `bytes` random bytes from the kernel as hex: the page token and the CSP nonces.
std::string RandomHex(std::size_t bytes) {
    std::string raw(bytes, '\0');
    std::size_t got = 0;
    while (got < bytes) {
        const ssize_t n = getrandom(raw.data() + got, bytes - got, 0);
        PITMAP_CHECK(n > 0 || errno == EINTR, "getrandom failed");
        if (n > 0) got += static_cast<std::size_t>(n);
    }
    static const char* kHex = "0123456789abcdef";
    std::string out;
    for (unsigned char c : raw) {
        out += kHex[c >> 4];
        out += kHex[c & 15];
    }
    return out;
}

FrontAnswer RoutedServer::Process(const FrontRequest& r) {
    BufferStream s(r);
    bool closed = false;
    process_request(s, r.last, closed, nullptr);
    FrontAnswer a;
    a.bytes = std::move(s.out());
    const std::size_t end = a.bytes.find("\r\n\r\n");
    std::string header = a.bytes.substr(0, end);
    std::transform(header.begin(), header.end(), header.begin(), [](unsigned char c) {
        return static_cast<char>(std::tolower(c));
    });
    // httplib answers a request it cannot parse with 400 but keeps the connection: what
    // follows on it is not to be trusted either.
    a.close = r.last || closed || end == std::string::npos ||
              header.rfind("http/1.1 400 ", 0) == 0 ||
              header.find("\r\nconnection: close") != std::string::npos;
    return a;
}

}  // namespace pitmap::proc::live
