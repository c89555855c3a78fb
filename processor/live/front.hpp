// SPDX-License-Identifier: MIT
// HttpFront: the accept loop in front of pitmap-live's HTTP handlers. It owns the public
// socket, reads each connection's request without blocking (one epoll thread), enforces the
// deadlines and connection caps below, and hands only complete requests (FrameRequest,
// http_rules.hpp) to a small worker pool; the answer is written back by the loop, again without
// blocking.
//
// Why: cpp-httplib 0.11.4 gives each connection one of its 8 pool threads from accept until
// the connection closes, with a read timeout per read() only. 8 clients sending a byte every
// 3 s, or 200 idle sockets, held every thread and every other request waited or timed out.
// Here a connection costs a file descriptor and a buffer until its request is complete, a
// worker only for the handler's run (milliseconds), and a connection that is slow, idle or
// one too many is closed:
//   - a request header must be complete within header_timeout_s (of the connection's accept
//     for its first request, of its first byte for the next ones), a body within
//     body_timeout_s of its header, an answer written within write_timeout_s;
//   - a kept-alive connection waits at most idle_timeout_s for its next request;
//   - at most max_connections_per_address connections per peer address and max_connections in
//     all: a new connection beyond either closes the one of that address (or of all) that has
//     been waiting for its request the longest; when every one is busy with a request, the new
//     one is answered 503 and closed. A client that is served within its deadlines is not
//     displaced by the slow ones: they are always older.
// Errors the front answers itself (400, 408, 413, 431, 501, 503) are JSON {"error": reason} with
// the security headers (http_rules.hpp) and close the connection (a connection that times out
// without having sent a byte is closed without a 408; an evicted one without an answer).
// Thread safety: Start/Stop from one thread; stats() from any. The handler runs on the worker
// threads, concurrently.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/result.hpp"

namespace pitmap::proc::live {

struct ConnectionLimits {
    std::size_t max_connections = 256;             // open connections in all
    std::size_t max_connections_per_address = 32;  // from one peer address
    double header_timeout_s = 5.0;  // a request's header, from accept or its first byte
    double body_timeout_s = 5.0;    // its body, from the end of its header
    double idle_timeout_s = 5.0;    // a kept-alive connection between two requests
    double write_timeout_s = 30.0;  // an answer, from its first byte written
    std::size_t max_header_bytes = 8192;
    std::size_t max_body_bytes = 65536;     // the live API takes no body; a little slack
    int max_requests_per_connection = 100;  // then the answer says Connection: close
    int worker_threads = 4;                 // run the handlers (the session's lock serialises)
    std::vector<std::string> Validate() const;
};

struct FrontRequest {
    std::string bytes;  // one complete request: header and body
    std::string peer_ip;
    int peer_port = 0;
    bool last = false;  // the connection closes after this answer
};
struct FrontAnswer {
    std::string bytes;   // the complete HTTP response
    bool close = false;  // close the connection once it is written
};
using FrontHandler = std::function<FrontAnswer(const FrontRequest&)>;

struct FrontStats {
    std::int64_t accepted = 0;
    std::int64_t open = 0;             // connections now
    std::int64_t requests = 0;         // handed to the handler
    std::int64_t evicted = 0;          // closed to make room for a new one
    std::int64_t refused = 0;          // new ones answered 503 (every one busy)
    std::int64_t header_timeouts = 0;  // header or body not complete in time (408)
    std::int64_t idle_closed = 0;      // kept-alive and silent for idle_timeout_s
    std::int64_t write_timeouts = 0;   // the answer not taken in time
    std::int64_t bad_requests = 0;     // 400, 413, 431, 501 from the front
    std::int64_t accept_failures = 0;  // accept() failed (e.g. out of file descriptors)
};

class HttpFront {
public:
    HttpFront(const ConnectionLimits& limits, FrontHandler handler);
    ~HttpFront();
    HttpFront(const HttpFront&) = delete;
    HttpFront& operator=(const HttpFront&) = delete;

    // Binds `address`:`port` (0 = any free port) and starts the loop and the workers; an
    // error names the address.
    Status Start(const std::string& address, int port);
    // Closes every connection (answers in progress are dropped) and joins the threads.
    void Stop();
    int port() const { return port_; }
    FrontStats stats() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    int port_ = 0;
};

}  // namespace pitmap::proc::live
