// SPDX-License-Identifier: MIT
// What pitmap live's server (server.hpp) and pitmap edit's (processor/edit/edit_server.hpp)
// share behind HttpFront (front.hpp): cpp-httplib's request parser, routing and response
// writer without its listener (RoutedServer: one complete request in, the answer's bytes out),
// and the random hex of page tokens and CSP nonces.
// Failure model: a request httplib cannot parse is answered 400 and the connection closed; the
// kernel's random source failing is a bug (PITMAP_CHECK). Every 4xx/5xx answer that a handler
// left without a body (httplib's own: no route 404, an unreadable request 400, a body too large
// 413, ...) gets {"error": "<status> <reason>"} as application/vnd.pitmap+json, the type of the
// handlers' own errors, so a page or script always reads JSON.
// Thread safety: Process may run on several threads at once (httplib's handlers must allow it).
// Including this header needs cpp-httplib's pkg-config flags (PkgConfig::CPPHTTPLIB).
#pragma once

#include <httplib.h>

#include <string>

#include "processor/live/front.hpp"

namespace pitmap::proc::live {

// `bytes` random bytes from the kernel as hex: page tokens and CSP nonces.
std::string RandomHex(std::size_t bytes);

// httplib's request parser, routing and response writer, without its listener.
class RoutedServer : public httplib::Server {
public:
    RoutedServer();
    // The answer to one complete request (FrameRequest, http_rules.hpp), and whether the
    // connection must close after it.
    FrontAnswer Process(const FrontRequest& r);
};

}  // namespace pitmap::proc::live
