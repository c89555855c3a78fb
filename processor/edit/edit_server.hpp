// SPDX-License-Identifier: MIT
// The HTTP server of `pitmap edit P`: the editing page and its API over an EditSession
// (edit_session.hpp), bound to 127.0.0.1 only.
//
//   GET  /                  the page (page.html, embedded at build time)
//   GET  /three.min.js, /OrbitControls.js   three.js r111 from Debian's libjs-three, read from
//                           its installed files at start (three_dir)
//   GET  /api/meta          counts per status, display set size and stride, the centre, edits,
//                           whether TVU is known, the re-run's state
//   GET  /api/points        the display set's positions: float32 little-endian x y z (metres
//                           east, north, up from the centre)
//   GET  /api/tvu           its TVU (95 %, m; NaN unknown): float32
//   GET  /api/status        its statuses: one byte each (survey/sounding_status.hpp codes)
//   POST /api/select        {"action": "reject"|"restore"|"count", "polygon": [[x, y], ...],
//                            "matrix": [16 numbers]}: selection.hpp's query over every
//                           sounding; reject and restore are edits, saved to P/edits.json before
//                           the answer {selected, changed, edits, seconds}
//   POST /api/undo          removes the last edit of the log
//   POST /api/rerun         starts `<pitmap> rerun P` (the pitmap executable beside this one,
//                           or the configured program); GET /api/rerun: its state and output
//                           (the last 200 lines). Edits are refused (409) while it runs: it
//                           reads P/edits.json at its start and holds P's lock.
// Security as pitmap live (processor/live/http_rules.hpp, front.hpp, routed_server.hpp): the
// accept loop with deadlines and caps, Host must name this server (DNS rebinding), a POST
// needs the page's token (X-Pitmap-Token; random per start, printed with the URL as ?token=,
// and in the page's <meta name="pitmap-token">) and no foreign Origin, and every response
// carries the security headers; the page's CSP admits its own inline script and style by a
// nonce per load and the two three.js files by the same nonce.
// The page is served without the token in the URL too (it is only a GET); what needs the token
// is a write.
// Failure model: Start fails naming the address, or a three.js file that cannot be read. A bad
// request is 400 with the reason; an edit that cannot be saved is 500 with the file's error.
// Thread safety: Start/Stop from one thread; the handlers run on the front's workers and go
// through the session's lock.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/edit/edit_session.hpp"
#include "processor/edit/rerun.hpp"
#include "processor/live/front.hpp"

namespace pitmap::proc::edit {

struct EditServerConfig {
    int port = 8767;                                        // 0 = any free port
    std::string three_dir = "/usr/share/javascript/three";  // Debian's libjs-three
    std::string out_dir;                                    // P (for the re-run's arguments)
    std::string rerun_program;                              // "" = no re-run button
    std::vector<std::string> rerun_args;                    // default: rerun P
    live::ConnectionLimits limits = [] {
        live::ConnectionLimits l;
        l.max_body_bytes = 1 << 20;  // a lasso of up to kMaxPolygonVertices vertices
        l.write_timeout_s = 120;     // the display set (up to ~30 MB) to a slow page
        return l;
    }();
    std::vector<std::string> Validate() const;
};

const char* EditPageHtml();

class EditServer {
public:
    EditServer(EditSession& session, const EditServerConfig& config);
    ~EditServer();
    EditServer(const EditServer&) = delete;
    EditServer& operator=(const EditServer&) = delete;

    // Binds 127.0.0.1 and starts serving on the front's threads.
    Status Start();
    void Stop();
    int port() const { return port_; }
    const std::string& token() const;
    // http://127.0.0.1:PORT/?token=TOKEN
    std::string url() const;
    RerunState rerun() const;

private:
    struct Impl;
    EditSession& session_;
    EditServerConfig config_;
    std::unique_ptr<Impl> impl_;
    int port_ = 0;
};

}  // namespace pitmap::proc::edit
