// SPDX-License-Identifier: MIT
#include "processor/edit/edit_server.hpp"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "processor/live/http_rules.hpp"
#include "processor/live/routed_server.hpp"

namespace pitmap::proc::edit {

namespace {

using json = nlohmann::json;
constexpr const char* kJsonType = "application/json";
constexpr const char* kBinaryType = "application/octet-stream";

Expected<std::string> ReadText(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    if (!f) return Error{path + ": cannot read (Debian's libjs-three: tools/install-deps.sh)"};
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
}

void ReplaceAll(std::string& s, const std::string& from, const std::string& to) {
    for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
        s.replace(at, from.size(), to);
}

// The query of POST /api/select; "" or the reason it is refused.
std::string ParseSelect(const std::string& body, std::string* action, SelectionQuery* q) {
    const json j = json::parse(body, nullptr, false);
    if (j.is_discarded() || !j.is_object()) return "the body is not a JSON object";
    if (!j.contains("action") || !j["action"].is_string()) return "no \"action\"";
    *action = j["action"].get<std::string>();
    if (*action != "reject" && *action != "restore" && *action != "count")
        return "action must be reject, restore or count";
    if (!j.contains("matrix") || !j["matrix"].is_array() || j["matrix"].size() != 16)
        return "\"matrix\" must be 16 numbers (column-major view-projection)";
    for (std::size_t i = 0; i < 16; ++i) {
        if (!j["matrix"][i].is_number()) return "\"matrix\" must be 16 numbers";
        q->view_projection[i] = j["matrix"][i].get<double>();
    }
    if (!j.contains("polygon") || !j["polygon"].is_array()) return "no \"polygon\"";
    if (j["polygon"].size() > kMaxPolygonVertices) return "the polygon has too many vertices";
    for (const json& v : j["polygon"]) {
        if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
            return "a polygon vertex is not [x, y]";
        q->polygon.push_back({v[0].get<double>(), v[1].get<double>()});
    }
    const auto problems = q->Validate();
    return problems.empty() ? "" : problems.front();
}

}  // namespace

std::vector<std::string> EditServerConfig::Validate() const {
    std::vector<std::string> p;
    if (port < 0 || port > 65535) p.push_back("edit: the port must lie in [0, 65535]");
    if (three_dir.empty()) p.push_back("edit: the three.js folder is empty");
    for (auto& l : limits.Validate()) p.push_back(std::move(l));
    return p;
}

struct EditServer::Impl {
    live::RoutedServer server;
    std::unique_ptr<live::HttpFront> front;
    std::string token;
    std::string page;  // with its token; the nonce placeholder left
    std::string three, orbit;
    std::vector<std::string> hosts;
    RerunProcess rerun;
};

EditServer::EditServer(EditSession& session, const EditServerConfig& config)
    : session_(session), config_(config), impl_(std::make_unique<Impl>()) {}

EditServer::~EditServer() {
    Stop();
}

const std::string& EditServer::token() const {
    return impl_->token;
}

std::string EditServer::url() const {
    return "http://127.0.0.1:" + std::to_string(port_) + "/?token=" + impl_->token;
}

RerunState EditServer::rerun() const {
    return impl_->rerun.state();
}

Status EditServer::Start() {
    Impl& m = *impl_;
    auto three = ReadText(config_.three_dir + "/three.min.js");
    if (!three) return three.error();
    auto orbit = ReadText(config_.three_dir + "/examples/js/controls/OrbitControls.js");
    if (!orbit) return orbit.error();
    m.three = std::move(*three);
    m.orbit = std::move(*orbit);
    m.token = live::RandomHex(16);
    m.page = EditPageHtml();
    ReplaceAll(m.page, "PITMAP_PAGE_TOKEN", m.token);
    m.hosts = live::AllowedHosts("127.0.0.1", {});
    live::RoutedServer& s = m.server;
    s.set_keep_alive_timeout(
        static_cast<time_t>(std::max(1.0, std::floor(config_.limits.idle_timeout_s))));
    s.set_keep_alive_max_count(static_cast<size_t>(config_.limits.max_requests_per_connection));
    s.set_payload_max_length(config_.limits.max_body_bytes);
    httplib::Headers security;
    for (const auto& h : live::SecurityHeaders()) security.emplace(h.name, h.value);
    s.set_default_headers(security);

    const auto send_json = [](httplib::Response& res, const json& j, int code = 200) {
        res.status = code;
        res.set_header("Cache-Control", "no-store");
        res.set_content(j.dump(-1, ' ', false, json::error_handler_t::replace), kJsonType);
    };
    s.set_pre_routing_handler(
        [this, send_json](const httplib::Request& req, httplib::Response& res) {
            using R = httplib::Server::HandlerResponse;
            const std::string host = req.get_header_value("Host");
            if (!live::HostAllowed(host, impl_->hosts)) {
                send_json(res,
                          {{"error",
                            "Host '" + host +
                                "' is not a name of this server (refused against DNS rebinding)"}},
                          403);
                return R::Handled;
            }
            if (req.method != "GET" && req.method != "HEAD") {
                const std::string why =
                    live::CheckWriteRequest({req.get_header_value(live::kTokenHeader),
                                             req.get_header_value("Origin"),
                                             req.get_header_value("Sec-Fetch-Site"),
                                             host},
                                            impl_->token);
                if (!why.empty()) {
                    send_json(res, {{"error", why}}, 403);
                    return R::Handled;
                }
            }
            return R::Unhandled;
        });
    s.Get("/", [this](const httplib::Request&, httplib::Response& res) {
        const std::string nonce = live::RandomHex(16);
        std::string page = impl_->page;
        ReplaceAll(page, "PITMAP_PAGE_NONCE", nonce);
        res.headers.erase("Content-Security-Policy");
        res.set_header("Content-Security-Policy", live::PageCsp(nonce));
        res.set_header("Cache-Control", "no-store");
        res.set_content(std::move(page), "text/html; charset=utf-8");
    });
    s.Get("/favicon.ico",
          [](const httplib::Request&, httplib::Response& res) { res.status = 204; });
    s.Get("/three.min.js", [this](const httplib::Request&, httplib::Response& res) {
        res.set_content(impl_->three, "text/javascript");
    });
    s.Get("/OrbitControls.js", [this](const httplib::Request&, httplib::Response& res) {
        res.set_content(impl_->orbit, "text/javascript");
    });
    const auto meta = [this]() {
        const survey::StatusCounts c = session_.Counts();
        json counts = json::object();
        for (int k = 0; k < survey::kNumSoundingStatus; ++k)
            counts[std::string(survey::ToString(static_cast<survey::SoundingStatus>(k)))] = c[k];
        const RerunState r = impl_->rerun.state();
        return json{{"soundings", session_.size()},
                    {"soundings_in_survey", session_.num_soundings()},
                    {"display", session_.display_size()},
                    {"stride", session_.display_stride()},
                    {"centre_enu_m", session_.centre()},
                    {"has_tvu", session_.has_tvu()},
                    {"edits", session_.num_edits()},
                    {"counts", counts},
                    {"description", session_.description()},
                    {"survey", std::filesystem::path(config_.out_dir).filename().string()},
                    {"rerun_available", !config_.rerun_program.empty()},
                    {"rerun", ToString(r.kind)}};
    };
    s.Get("/api/meta", [meta, send_json](const httplib::Request&, httplib::Response& res) {
        send_json(res, meta());
    });
    s.Get("/api/points", [this](const httplib::Request&, httplib::Response& res) {
        res.set_header("Cache-Control", "no-store");
        res.set_content(session_.DisplayPositions(), kBinaryType);
    });
    s.Get("/api/tvu", [this](const httplib::Request&, httplib::Response& res) {
        res.set_header("Cache-Control", "no-store");
        res.set_content(session_.DisplayTvu(), kBinaryType);
    });
    s.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
        res.set_header("Cache-Control", "no-store");
        res.set_content(session_.DisplayStatus(), kBinaryType);
    });
    s.Post("/api/select", [this, send_json](const httplib::Request& req, httplib::Response& res) {
        std::string action;
        SelectionQuery q;
        if (const std::string why = ParseSelect(req.body, &action, &q); !why.empty())
            return send_json(res, {{"error", "select: " + why}}, 400);
        if (action == "count") {
            return send_json(res,
                             {{"selected", session_.Select(q).size()},
                              {"changed", 0},
                              {"edits", session_.num_edits()}});
        }
        if (impl_->rerun.running())
            return send_json(res, {{"error", "a re-run is running: edits wait for it"}}, 409);
        auto r = session_.Apply(action == "reject" ? EditAction::kReject : EditAction::kRestore, q);
        if (!r) return send_json(res, {{"error", r.error().message}}, 500);
        send_json(res,
                  {{"selected", r->selected},
                   {"changed", r->changed},
                   {"edits", r->edits},
                   {"seconds", r->seconds}});
    });
    s.Post("/api/undo", [this, send_json](const httplib::Request&, httplib::Response& res) {
        if (impl_->rerun.running())
            return send_json(res, {{"error", "a re-run is running: edits wait for it"}}, 409);
        auto r = session_.Undo();
        if (!r) return send_json(res, {{"error", r.error().message}}, 409);
        send_json(res, {{"changed", r->changed}, {"edits", r->edits}});
    });
    const auto rerun_json = [this]() {
        const RerunState r = impl_->rerun.state();
        return json{{"state", ToString(r.kind)},
                    {"exit_code", r.exit_code},
                    {"runs", r.runs},
                    {"seconds", r.seconds},
                    {"lines", r.lines}};
    };
    s.Get("/api/rerun", [rerun_json, send_json](const httplib::Request&, httplib::Response& res) {
        send_json(res, rerun_json());
    });
    s.Post("/api/rerun",
           [this, rerun_json, send_json](const httplib::Request&, httplib::Response& res) {
               if (config_.rerun_program.empty())
                   return send_json(res, {{"error", "no re-run program configured"}}, 409);
               const std::vector<std::string> args =
                   config_.rerun_args.empty() ? std::vector<std::string>{"rerun", config_.out_dir}
                                              : config_.rerun_args;
               if (auto st = impl_->rerun.Start(config_.rerun_program, args); !st)
                   return send_json(res, {{"error", st.error().message}}, 409);
               send_json(res, rerun_json());
           });

    m.front = std::make_unique<live::HttpFront>(
        config_.limits, [this](const live::FrontRequest& r) { return impl_->server.Process(r); });
    if (auto st = m.front->Start("127.0.0.1", config_.port); !st) return st;
    port_ = m.front->port();
    return Ok{};
}

void EditServer::Stop() {
    if (impl_ && impl_->front) impl_->front->Stop();
}

}  // namespace pitmap::proc::edit
