// SPDX-License-Identifier: MIT
#include "processor/live/server.hpp"

#include <httplib.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <mutex>

#include "processor/live/http_rules.hpp"
#include "processor/live/routed_server.hpp"

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

// Whether the request spends from a budget: not a page on this machine unless asked.
bool Budgeted(const ServerConfig& config, const httplib::Request& req) {
    return config.budget_loopback || !IsLoopbackAddress(req.remote_addr);
}

// The type httplib does not compress again (it compresses application/json itself).
constexpr const char* kJsonType = "application/vnd.pitmap+json";

void ReplaceAll(std::string& s, const std::string& from, const std::string& to) {
    for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
        s.replace(at, from.size(), to);
}

bool IsWildcard(const std::string& address) {
    return address == "0.0.0.0" || address == "::" || address == "[::]";
}

// The addresses of this machine's interfaces as a Host header gives them (IPv6 in brackets;
// link-local IPv6 left out: a browser's Host never carries its zone).
std::vector<std::string> InterfaceAddresses() {
    std::vector<std::string> out;
    ifaddrs* list = nullptr;
    if (getifaddrs(&list) != 0) return out;
    for (ifaddrs* a = list; a; a = a->ifa_next) {
        if (!a->ifa_addr) continue;
        char buf[INET6_ADDRSTRLEN] = {};
        if (a->ifa_addr->sa_family == AF_INET) {
            inet_ntop(AF_INET,
                      &reinterpret_cast<const sockaddr_in*>(a->ifa_addr)->sin_addr,
                      buf,
                      sizeof(buf));
            out.emplace_back(buf);
        } else if (a->ifa_addr->sa_family == AF_INET6) {
            const auto* v6 = reinterpret_cast<const sockaddr_in6*>(a->ifa_addr);
            if (IN6_IS_ADDR_LINKLOCAL(&v6->sin6_addr)) continue;
            inet_ntop(AF_INET6, &v6->sin6_addr, buf, sizeof(buf));
            out.push_back("[" + std::string(buf) + "]");
        }
    }
    freeifaddrs(list);
    return out;
}

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
    for (const auto& h : allowed_hosts) {
        if (HostName(h).empty() && HostName("[" + h + "]").empty())
            p.push_back("live: --allow-host " + h + " is not a host name or address");
    }
    for (auto& l : limits.Validate()) p.push_back(std::move(l));
    return p;
}

struct LiveServer::Impl {
    RoutedServer server;
    std::unique_ptr<HttpFront> front;
    std::string token;  // the page's, for POST (random per start)
    std::string page;   // the page with its token, a nonce placeholder left
    mutable std::mutex hosts_mutex;
    std::vector<std::string> hosts;
    std::chrono::steady_clock::time_point hosts_read;
    bool wildcard = false;
    std::vector<std::string> base_hosts;

    // Bound to a wildcard, a Host not known may be an address the machine got since: the
    // interfaces are read again, at most every 5 s (a rebinding attacker cannot make it cost).
    bool HostKnown(const std::string& host_header) {
        std::lock_guard<std::mutex> lock(hosts_mutex);
        if (HostAllowed(host_header, hosts)) return true;
        const auto now = std::chrono::steady_clock::now();
        if (!wildcard || now - hosts_read < std::chrono::seconds(5)) return false;
        ReadHostsLocked(now);
        return HostAllowed(host_header, hosts);
    }
    void ReadHostsLocked(std::chrono::steady_clock::time_point now) {
        hosts = base_hosts;
        if (wildcard) {
            for (auto& a : InterfaceAddresses()) {
                if (std::find(hosts.begin(), hosts.end(), a) == hosts.end()) hosts.push_back(a);
            }
        }
        hosts_read = now;
    }
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
    Impl& m = *impl_;
    RoutedServer& s = m.server;
    m.token = RandomHex(16);
    m.page = LivePageHtml();
    ReplaceAll(m.page, "PITMAP_PAGE_TOKEN", m.token);
    m.wildcard = IsWildcard(config_.bind_address);
    m.base_hosts = AllowedHosts(config_.bind_address, config_.allowed_hosts);
    {
        std::lock_guard<std::mutex> lock(m.hosts_mutex);
        m.ReadHostsLocked(std::chrono::steady_clock::now());
    }
    // httplib writes Keep-Alive: timeout, max from these; the front enforces them.
    s.set_keep_alive_timeout(
        static_cast<time_t>(std::max(1.0, std::floor(config_.limits.idle_timeout_s))));
    s.set_keep_alive_max_count(static_cast<size_t>(config_.limits.max_requests_per_connection));
    s.set_payload_max_length(config_.limits.max_body_bytes);
    httplib::Headers security;
    for (const auto& h : SecurityHeaders()) security.emplace(h.name, h.value);
    s.set_default_headers(security);

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
        if (Budgeted(config_, req)) {
            budget_.Spend(client, static_cast<std::int64_t>(body.size()), SteadyUtime());
        } else {
            unbudgeted_bytes_.fetch_add(static_cast<std::int64_t>(body.size()));
        }
        res.status = code;
        res.set_header("Cache-Control", "no-store");
        res.set_content(std::move(body), kJsonType);
    };
    const auto bad_request =
        [send_json](const httplib::Request& req, httplib::Response& res, const std::string& why) {
            send_json(req, res, {{"error", why}}, 400);
        };
    // Before any route: the Host, `client=` on every endpoint, the token and origin of writes.
    s.set_pre_routing_handler(
        [this, send_json](const httplib::Request& req, httplib::Response& res) {
            using R = httplib::Server::HandlerResponse;
            const std::string host = req.get_header_value("Host");
            if (!impl_->HostKnown(host)) {
                send_json(req,
                          res,
                          {{"error",
                            "Host '" + host +
                                "' is not a name of this server (refused against DNS rebinding; "
                                "pitmap-live --allow-host NAME adds one)"}},
                          403);
                return R::Handled;
            }
            if (const std::string why = CheckClientParams(req.params); !why.empty()) {
                send_json(req, res, {{"error", why}}, 400);
                return R::Handled;
            }
            if (req.method != "GET" && req.method != "HEAD") {
                const std::string why = CheckWriteRequest({req.get_header_value(kTokenHeader),
                                                           req.get_header_value("Origin"),
                                                           req.get_header_value("Sec-Fetch-Site"),
                                                           host},
                                                          impl_->token);
                if (!why.empty()) {
                    send_json(req, res, {{"error", why}}, 403);
                    return R::Handled;
                }
            }
            return R::Unhandled;
        });
    s.Get("/", [this](const httplib::Request&, httplib::Response& res) {
        // A nonce per load: the CSP admits the page's own inline script and style only.
        const std::string nonce = RandomHex(16);
        std::string page = impl_->page;
        ReplaceAll(page, "PITMAP_PAGE_NONCE", nonce);
        res.headers.erase("Content-Security-Policy");
        res.set_header("Content-Security-Policy", PageCsp(nonce));
        res.set_header("Cache-Control", "no-store");
        res.set_content(std::move(page), "text/html; charset=utf-8");
    });
    s.Get("/favicon.ico",
          [](const httplib::Request&, httplib::Response& res) { res.status = 204; });
    s.Get("/api/status", [this, send_json](const httplib::Request& req, httplib::Response& res) {
        nlohmann::json j = session_.StatusJson(WallUtime());
        const std::string client = ClientKey(req);
        const std::int64_t now = SteadyUtime();
        j["budget"] = {{"applies", Budgeted(config_, req)},
                       {"rate_bytes_per_s", budget_.rate_bytes_per_s()},
                       {"client_rate_bytes_per_s", budget_.ShareBytesPerS(now)},
                       {"clients", budget_.ActiveClients(now)},
                       {"clients_evicted", budget_.evicted()},
                       {"available_bytes", budget_.Available(client, now)},
                       {"client_spent_bytes", budget_.spent(client)},
                       {"spent_bytes", budget_.spent()}};
        const FrontStats c = connections();
        j["http"] = {{"open", c.open},
                     {"accepted", c.accepted},
                     {"requests", c.requests},
                     {"evicted", c.evicted},
                     {"refused", c.refused},
                     {"timed_out", c.header_timeouts + c.write_timeouts},
                     {"idle_closed", c.idle_closed},
                     {"bad_requests", c.bad_requests}};
        send_json(req, res, j);
    });
    s.Get("/api/alarms", [this, send_json](const httplib::Request& req, httplib::Response& res) {
        send_json(req, res, session_.AlarmsJson());
    });
    s.Get("/api/tiles",
          [this, send_json, bad_request](const httplib::Request& req, httplib::Response& res) {
              const LiveQuery q = ParseLiveQuery(req.params);
              if (!q.error.empty()) return bad_request(req, res, q.error);
              std::int64_t share = Budgeted(config_, req)
                                       ? budget_.Available(ClientKey(req), SteadyUtime()) * 6 / 10
                                       : -1;
              if (q.max_bytes >= 0) share = share < 0 ? q.max_bytes : std::min(share, q.max_bytes);
              send_json(req, res, session_.TilesJson(q.since, share));
          });
    s.Get("/api/soundings",
          [this, send_json, bad_request](const httplib::Request& req, httplib::Response& res) {
              const LiveQuery q = ParseLiveQuery(req.params);
              if (!q.error.empty()) return bad_request(req, res, q.error);
              std::int64_t share =
                  Budgeted(config_, req) ? budget_.Available(ClientKey(req), SteadyUtime()) : -1;
              if (q.max_bytes >= 0) share = share < 0 ? q.max_bytes : std::min(share, q.max_bytes);
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
        // The answer names the file only: the server's directories are none of the page's
        // business (and its errors say "the snapshot directory" instead).
        auto path = session_.WriteSnapshot(config_.snapshot_dir);
        if (!path) {
            std::string why = path.error().message;
            ReplaceAll(why, config_.snapshot_dir, "the snapshot directory");
            return send_json(req, res, {{"error", why}}, 409);
        }
        send_json(req, res, {{"file", std::filesystem::path(*path).filename().string()}});
    });

    m.front = std::make_unique<HttpFront>(
        config_.limits, [this](const FrontRequest& r) { return impl_->server.Process(r); });
    if (auto st = m.front->Start(config_.bind_address, config_.port); !st) return st;
    port_ = m.front->port();
    return Ok{};
}

void LiveServer::Stop() {
    if (impl_ && impl_->front) impl_->front->Stop();
}

FrontStats LiveServer::connections() const {
    return impl_->front ? impl_->front->stats() : FrontStats{};
}

std::vector<std::string> LiveServer::allowed_hosts() const {
    std::lock_guard<std::mutex> lock(impl_->hosts_mutex);
    return impl_->hosts;
}

}  // namespace pitmap::proc::live
