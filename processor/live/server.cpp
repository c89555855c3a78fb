// SPDX-License-Identifier: MIT
#include "processor/live/server.hpp"

#include <httplib.h>
#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace pitmap::proc::live {

namespace {

std::int64_t WallUtime() {
    return std::chrono::duration_cast<std::chrono::microseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
}

std::int64_t SteadyUtime() {
    return std::chrono::duration_cast<std::chrono::microseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

// gzip at level 1: most of the size gone for little CPU (httplib's own choice for a browser
// is brotli at a level that cost 80 % of pitmap-live's CPU at 1x). Empty on failure.
std::string Gzip(const std::string& in) {
    z_stream z{};
    if (deflateInit2(&z, 1, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) return {};
    std::string out(deflateBound(&z, static_cast<uLong>(in.size())) + 32, '\0');
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
    z.avail_in = static_cast<uInt>(in.size());
    z.next_out = reinterpret_cast<Bytef*>(out.data());
    z.avail_out = static_cast<uInt>(out.size());
    const int rc = deflate(&z, Z_FINISH);
    out.resize(z.total_out);
    deflateEnd(&z);
    return rc == Z_STREAM_END ? out : std::string();
}

// The budget key of a request: the peer address, plus the page's id when it is well formed
// (ParseLiveQuery's check; bounded length and characters).
std::string ClientKey(const httplib::Request& req) {
    std::string key = req.remote_addr;
    if (req.has_param("client")) {
        const LiveQuery q = ParseLiveQuery({{"client", req.get_param_value("client")}});
        if (q.error.empty()) key += "/" + q.client;
    }
    return key;
}

// The type httplib does not compress again (it compresses application/json itself).
constexpr const char* kJsonType = "application/vnd.pitmap+json";

}  // namespace

std::vector<std::string> ServerConfig::Validate() const {
    std::vector<std::string> p;
    if (bind_address.empty()) p.push_back("live: the bind address is empty");
    if (port < 0 || port > 65535) p.push_back("live: the port must lie in [0, 65535]");
    if (!(budget_bytes_per_s >= 1000) || !std::isfinite(budget_bytes_per_s))
        p.push_back("live: the byte budget must be at least 1000 bytes/s");
    if (!(budget_burst_s > 0) || !std::isfinite(budget_burst_s))
        p.push_back("live: the budget burst must be > 0 s");
    if (max_clients < 1 || max_clients > 1000)
        p.push_back("live: max_clients must lie in [1, 1000]");
    if (!(client_idle_s > 0) || !std::isfinite(client_idle_s))
        p.push_back("live: client_idle_s must be > 0");
    return p;
}

struct LiveServer::Impl {
    httplib::Server server;
};

LiveServer::LiveServer(LiveSession& session, const ServerConfig& config)
    : session_(session),
      config_(config),
      budget_(config.budget_bytes_per_s,
              config.budget_burst_s,
              config.max_clients,
              config.client_idle_s),
      impl_(std::make_unique<Impl>()) {}

LiveServer::~LiveServer() {
    Stop();
}

Status LiveServer::Start() {
    httplib::Server& s = impl_->server;
    // The client's budget is spent by what goes on the wire: gzip-compressed when the client
    // takes it. A request whose `client` is malformed spends from its address's budget.
    const auto send_json = [this](const httplib::Request& req,
                                  httplib::Response& res,
                                  const nlohmann::json& j,
                                  int code = 200) {
        const std::string client = ClientKey(req);
        // Text from the wire (host and channel names) may be any bytes: replaced, never thrown.
        std::string body = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
        if (req.get_header_value("Accept-Encoding").find("gzip") != std::string::npos) {
            std::string z = Gzip(body);
            if (!z.empty()) {
                body = std::move(z);
                res.set_header("Content-Encoding", "gzip");
            }
        }
        budget_.Spend(client, static_cast<std::int64_t>(body.size()), SteadyUtime());
        res.status = code;
        res.set_header("Cache-Control", "no-store");
        res.set_content(std::move(body), kJsonType);
    };
    const auto bad_request =
        [send_json](const httplib::Request& req, httplib::Response& res, const std::string& why) {
            send_json(req, res, {{"error", why}}, 400);
        };
    s.Get("/", [](const httplib::Request&, httplib::Response& res) {
        res.set_content(LivePageHtml(), "text/html; charset=utf-8");
    });
    s.Get("/favicon.ico",
          [](const httplib::Request&, httplib::Response& res) { res.status = 204; });
    s.Get("/api/status", [this, send_json](const httplib::Request& req, httplib::Response& res) {
        nlohmann::json j = session_.StatusJson(WallUtime());
        const std::string client = ClientKey(req);
        const std::int64_t now = SteadyUtime();
        j["budget"] = {{"rate_bytes_per_s", budget_.rate_bytes_per_s()},
                       {"client_rate_bytes_per_s", budget_.ShareBytesPerS(now)},
                       {"clients", budget_.ActiveClients(now)},
                       {"clients_evicted", budget_.evicted()},
                       {"available_bytes", budget_.Available(client, now)},
                       {"client_spent_bytes", budget_.spent(client)},
                       {"spent_bytes", budget_.spent()}};
        send_json(req, res, j);
    });
    s.Get("/api/alarms", [this, send_json](const httplib::Request& req, httplib::Response& res) {
        send_json(req, res, session_.AlarmsJson());
    });
    s.Get("/api/tiles",
          [this, send_json, bad_request](const httplib::Request& req, httplib::Response& res) {
              const LiveQuery q = ParseLiveQuery(req.params);
              if (!q.error.empty()) return bad_request(req, res, q.error);
              std::int64_t share = budget_.Available(ClientKey(req), SteadyUtime()) * 6 / 10;
              if (q.max_bytes >= 0) share = std::min(share, q.max_bytes);
              send_json(req, res, session_.TilesJson(q.since, share));
          });
    s.Get("/api/soundings",
          [this, send_json, bad_request](const httplib::Request& req, httplib::Response& res) {
              const LiveQuery q = ParseLiveQuery(req.params);
              if (!q.error.empty()) return bad_request(req, res, q.error);
              std::int64_t share = budget_.Available(ClientKey(req), SteadyUtime());
              if (q.max_bytes >= 0) share = std::min(share, q.max_bytes);
              send_json(req, res, session_.SoundingsJson(q.since, share));
          });
    s.Post("/api/snapshot", [this, send_json](const httplib::Request& req, httplib::Response& res) {
        if (config_.snapshot_dir.empty()) {
            return send_json(
                req,
                res,
                {{"error", "no snapshot directory configured (pitmap-live --out DIR)"}},
                409);
        }
        auto path = session_.WriteSnapshot(config_.snapshot_dir);
        if (!path) return send_json(req, res, {{"error", path.error().message}}, 409);
        send_json(req, res, {{"path", *path}});
    });

    if (config_.port == 0) {
        port_ = s.bind_to_any_port(config_.bind_address);
        if (port_ < 0) return Error{"cannot bind " + config_.bind_address + " (any port)"};
    } else {
        if (!s.bind_to_port(config_.bind_address, config_.port)) {
            return Error{"cannot bind " + config_.bind_address + ":" +
                         std::to_string(config_.port) +
                         " (in use, or not an address of this machine)"};
        }
        port_ = config_.port;
    }
    thread_ = std::thread([this] { impl_->server.listen_after_bind(); });
    return Ok{};
}

void LiveServer::Stop() {
    if (impl_) impl_->server.stop();
    if (thread_.joinable()) thread_.join();
}

}  // namespace pitmap::proc::live
