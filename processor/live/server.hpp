// SPDX-License-Identifier: MIT
// The live page's HTTP server, bound to 127.0.0.1 by default.
//
//   GET  /                 the page (page.html, embedded at build time; no other asset)
//   GET  /api/status       status, alarms, counters, grid statistics, the link budget
//   GET  /api/alarms       active alarms and the latest raised/cleared transitions
//   GET  /api/tiles?since=V[&max_bytes=N]      grid tiles changed after version V, holidays
//   GET  /api/soundings?since=S[&max_bytes=N]  recent soundings after sequence S, the track
//   POST /api/snapshot     writes the coverage grid as a GeoTIFF into the snapshot directory;
//                          answers its file name (never a path of the server)
// Every request may add `client=ID` (the page sends a random id per page load; 1-32 characters
// of A-Z a-z 0-9 _ -, else HTTP 400 on every endpoint). Every response spends from the budget
// of its client, the peer address plus that id (ClientBudgets, budget.hpp: the link rate shared
// equally among the active clients, max_clients tracked): the tiles may take 60 % of what the
// client has, the soundings what remains; both say when they were thinned. Pages on this
// machine (a loopback peer: 127.0.0.0/8, ::1) are not budgeted unless budget_loopback (pitmap-live
// --budget-loopback): the budget stands for the radio link, which they do not use, and at the
// default rate a fast replay thinned a local page for nothing. A bad query parameter is HTTP 400
// with the reason. Every 4xx and 5xx answer, httplib's own included (no route, a request it
// cannot read), has a JSON body {"error": "..."}.
//
// Design: the public socket belongs to HttpFront (front.hpp), an epoll loop that reads
// requests without blocking, enforces ConnectionLimits (header, body, idle and write deadlines;
// connections per address and in all) and hands only complete requests to cpp-httplib's
// parser and routing (Server::process_request over an in-memory stream, on the front's
// workers). httplib 0.11.4's own listener holds one of its 8 threads per connection until it
// closes, with per-read timeouts only, so 8 slow or idle clients starved everyone. Its
// per-connection entry (process_and_close_socket) is private, but the protected
// process_request takes any Stream: complete requests go to it directly, without a relay over
// an internal socket (a second parse, a loopback hop, a peer address to carry across).
// Checks on every request, before routing (http_rules.hpp):
//   - Host must name this server (DNS rebinding): localhost, 127.0.0.1, [::1] (any port), the
//     bind address, --allow-host names; bound to a wildcard (0.0.0.0, ::), also the addresses
//     of this machine's interfaces (read again, at most every 5 s, when a Host is not known).
//     Else 403 with the reason.
//   - A POST must carry the page's token (X-Pitmap-Token; a random one per server start, in
//     the page's <meta name="pitmap-token">) and must not come from another origin (Origin,
//     Sec-Fetch-Site). Else 403: a cross-origin form or text/plain POST cannot write files.
//   - every `client=` as above, else 400.
// Every response carries Content-Security-Policy (default-src 'none'; the page's own: its
// inline script and style by a nonce per load, fetch to itself, data: images),
// X-Content-Type-Options nosniff, X-Frame-Options DENY (and frame-ancestors 'none'),
// Referrer-Policy no-referrer, Cross-Origin-Resource-Policy same-origin.
// Thread safety: Start/Stop from one thread; the handlers run on the front's workers and go
// through LiveSession's lock.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/live/budget.hpp"
#include "processor/live/front.hpp"
#include "processor/live/session.hpp"

namespace pitmap::proc::live {

struct ServerConfig {
    std::string bind_address = "127.0.0.1";
    int port = 8765;  // 0 = any free port (see LiveServer::port)
    double budget_bytes_per_s = 50'000;
    double budget_burst_s = 2.0;
    bool budget_loopback = false;  // loopback pages budgeted too (else they take what they ask)
    std::size_t max_clients = 16;  // clients with a budget of their own; beyond: LRU evicted
    double client_idle_s = 10.0;   // a client silent this long no longer takes a share
    std::string snapshot_dir;      // "" = snapshots refused
    // Further Host names (or addresses) the server answers to (pitmap-live --allow-host).
    std::vector<std::string> allowed_hosts;
    ConnectionLimits limits;  // deadlines and caps of the front (front.hpp)
    std::vector<std::string> Validate() const;
};

const char* LivePageHtml();

class LiveServer {
public:
    LiveServer(LiveSession& session, const ServerConfig& config);
    ~LiveServer();
    LiveServer(const LiveServer&) = delete;
    LiveServer& operator=(const LiveServer&) = delete;

    // Binds and starts serving on a thread; an error names the address.
    Status Start();
    void Stop();
    int port() const { return port_; }
    // Bytes of every JSON answer, budgeted or not.
    std::int64_t bytes_served() const { return budget_.spent() + unbudgeted_bytes_.load(); }
    const ClientBudgets& budgets() const { return budget_; }
    FrontStats connections() const;
    // The names a Host header may give now (lower case, IPv6 in brackets).
    std::vector<std::string> allowed_hosts() const;

private:
    struct Impl;
    LiveSession& session_;
    ServerConfig config_;
    ClientBudgets budget_;
    std::atomic<std::int64_t> unbudgeted_bytes_{0};
    std::unique_ptr<Impl> impl_;
    int port_ = 0;
};

}  // namespace pitmap::proc::live
