// SPDX-License-Identifier: MIT
// The live page's HTTP server (Debian's cpp-httplib), bound to 127.0.0.1 by default.
//
//   GET  /                 the page (page.html, embedded at build time; no other asset)
//   GET  /api/status       status, alarms, counters, grid statistics, the link budget
//   GET  /api/alarms       active alarms and the latest raised/cleared transitions
//   GET  /api/tiles?since=V[&max_bytes=N]      grid tiles changed after version V, holidays
//   GET  /api/soundings?since=S[&max_bytes=N]  recent soundings after sequence S, the track
//   POST /api/snapshot     writes the coverage grid as a GeoTIFF into the snapshot directory
// Every request may add `client=ID` (the page sends a random id per page load). Every response
// spends from the budget of its client, the peer address plus that id (ClientBudgets,
// budget.hpp: the link rate shared equally among the active clients, max_clients tracked): the
// tiles may take 60 % of what the client has, the soundings what remains; both say when they
// were thinned. A bad query parameter is HTTP 400 with the reason.
// Thread safety: Start/Stop from one thread; the handlers run on httplib's pool and go through
// LiveSession's lock.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "common/result.hpp"
#include "processor/live/budget.hpp"
#include "processor/live/session.hpp"

namespace pitmap::proc::live {

struct ServerConfig {
    std::string bind_address = "127.0.0.1";
    int port = 8765;  // 0 = any free port (see LiveServer::port)
    double budget_bytes_per_s = 50'000;
    double budget_burst_s = 2.0;
    std::size_t max_clients = 16;  // clients with a budget of their own; beyond: LRU evicted
    double client_idle_s = 10.0;   // a client silent this long no longer takes a share
    std::string snapshot_dir;      // "" = snapshots refused
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
    std::int64_t bytes_served() const { return budget_.spent(); }
    const ClientBudgets& budgets() const { return budget_; }

private:
    struct Impl;
    LiveSession& session_;
    ServerConfig config_;
    ClientBudgets budget_;
    std::unique_ptr<Impl> impl_;
    std::thread thread_;
    int port_ = 0;
};

}  // namespace pitmap::proc::live
