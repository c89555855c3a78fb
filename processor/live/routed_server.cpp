// SPDX-License-Identifier: MIT
#include "processor/live/routed_server.hpp"

#include <sys/random.h>

#include <algorithm>
#include <cctype>
#include <cerrno>

#include <nlohmann/json.hpp>

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

// `r` without its Range header lines: every answer here is whole (RFC 9110 14.2 lets a server
// ignore Range). httplib 0.11.4 answers a range past the end of a handler's body with 416 and
// an empty body, after its error handler has run.
FrontRequest WithoutRange(const FrontRequest& r) {
    const std::size_t head_end = r.bytes.find("\r\n\r\n");
    if (head_end == std::string::npos) return r;
    std::string lower = r.bytes.substr(0, head_end);
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) {
        return static_cast<char>(std::tolower(c));
    });
    if (lower.find("\r\nrange:") == std::string::npos) return r;
    // The request line and every header line but Range's, then "\r\n\r\n" and the body.
    FrontRequest out = r;
    out.bytes.clear();
    for (std::size_t at = 0; at < head_end;) {
        const std::size_t eol = std::min(r.bytes.find("\r\n", at), head_end);
        if (at == 0 || lower.compare(at, 6, "range:") != 0) {
            if (at > 0) out.bytes += "\r\n";
            out.bytes.append(r.bytes, at, eol - at);
        }
        at = eol + 2;
    }
    out.bytes.append(r.bytes, head_end, std::string::npos);
    return out;
}

// RFC 9110 section 15's reason phrases of the answers httplib gives by itself.
const char* ReasonPhrase(int status) {
    switch (status) {
        case 400:
            return "Bad Request";
        case 403:
            return "Forbidden";
        case 404:
            return "Not Found";
        case 405:
            return "Method Not Allowed";
        case 408:
            return "Request Timeout";
        case 411:
            return "Length Required";
        case 413:
            return "Content Too Large";
        case 414:
            return "URI Too Long";
        case 415:
            return "Unsupported Media Type";
        case 416:
            return "Range Not Satisfiable";
        case 417:
            return "Expectation Failed";
        case 431:
            return "Request Header Fields Too Large";
        case 500:
            return "Internal Server Error";
        case 501:
            return "Not Implemented";
        case 503:
            return "Service Unavailable";
        default:
            return status >= 500 ? "Server Error" : "Client Error";
    }
}

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

RoutedServer::RoutedServer() {
    set_error_handler(HandlerWithResponse([](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return HandlerResponse::Unhandled;
        std::string why = std::to_string(res.status) + " " + ReasonPhrase(res.status);
        if (res.status == 400) why += ": the request line, a header or the body cannot be read";
        if (res.status == 404) why += ": no " + req.method + " " + req.path + " here";
        if (res.status == 405) why += ": " + req.method + " is not allowed on " + req.path;
        res.set_content(nlohmann::json{{"error", why}}.dump(
                            -1, ' ', false, nlohmann::json::error_handler_t::replace),
                        "application/vnd.pitmap+json");
        res.set_header("Cache-Control", "no-store");
        return HandlerResponse::Handled;
    }));
}

FrontAnswer RoutedServer::Process(const FrontRequest& request) {
    const FrontRequest r = WithoutRange(request);
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
