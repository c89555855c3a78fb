// SPDX-License-Identifier: MIT
// The rules pitmap-live's HTTP front (front.hpp) and server (server.hpp) apply to a request,
// as pure functions of its bytes and headers: no sockets, no clocks.
//
// FrameRequest: where one HTTP/1.1 request ends in the bytes received so far (the header up to
// its empty line, then Content-Length bytes of body), so that only complete requests reach
// httplib. A chunked body or a malformed or over-long header is refused with the status to
// answer (the live API takes no request body).
// HostAllowed: the Host header against the names the server answers to (DNS rebinding: a page
// of another site resolved to this address sends that site's name).
// CheckWriteRequest: a request that changes something (POST) must carry the page's token and
// must not come from another origin (a cross-origin `text/plain` form POST needs no CORS
// preflight, so the token is what refuses it).
// CheckClientParams: every `client=` value against ParseLiveQuery's rule (budget.hpp).
// The security headers: set on every response.
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace pitmap::proc::live {

struct RequestFrame {
    enum class Kind { kNeedMore, kComplete, kError };
    Kind kind = Kind::kNeedMore;
    std::size_t skipped = 0;       // leading empty lines (RFC 9112 2.2) to drop before it
    std::size_t header_bytes = 0;  // kComplete / kNeedMore with a full header: through "\r\n\r\n"
    std::size_t total_bytes = 0;   // kComplete: header plus body
    int status = 0;                // kError: the HTTP status to answer (400, 413, 431, 501)
    std::string reason;            // kError: why
};
// `bytes`: what the connection has received and not yet consumed.
RequestFrame FrameRequest(std::string_view bytes,
                          std::size_t max_header_bytes,
                          std::size_t max_body_bytes);

// The host part of a Host header, lower-cased and without the port ("[::1]:8765" -> "[::1]",
// "Example:80" -> "example"); "" when the header is malformed (empty, a bad port, a bare IPv6
// address, characters outside a host name or address).
std::string HostName(std::string_view host_header);
// True when HostName(host_header) is one of `allowed` (lower-case names, IPv6 in brackets).
bool HostAllowed(std::string_view host_header, const std::vector<std::string>& allowed);
// The names a server bound to `bind_address` answers to: localhost, 127.0.0.1, [::1], the bind
// address itself, `extra` (lower-cased; an IPv6 address gets brackets).
std::vector<std::string> AllowedHosts(const std::string& bind_address,
                                      const std::vector<std::string>& extra);

// The header that carries the page's token (a custom header: another origin cannot send it
// without a CORS preflight, which this server never grants).
inline constexpr const char* kTokenHeader = "X-Pitmap-Token";
struct WriteRequestHeaders {
    std::string token;           // kTokenHeader
    std::string origin;          // Origin
    std::string sec_fetch_site;  // Sec-Fetch-Site
    std::string host;            // Host
};
// "" when a write request may go on, else the reason to refuse it (HTTP 403): the token must
// equal `token` (non-empty); an Origin, when present, must be http://<Host>; Sec-Fetch-Site,
// when present, must be same-origin. A missing header is "".
std::string CheckWriteRequest(const WriteRequestHeaders& h, const std::string& token);

// "" when every `client` parameter is 1-32 characters of A-Z a-z 0-9 _ - (ParseLiveQuery),
// else its reason (HTTP 400).
std::string CheckClientParams(const std::multimap<std::string, std::string>& params);

// The headers every response carries; the page's CSP replaces the default one.
struct HeaderField {
    const char* name;
    const char* value;
};
// Content-Security-Policy default-src 'none' with frame-ancestors 'none', nosniff,
// X-Frame-Options DENY, Referrer-Policy no-referrer.
const std::vector<HeaderField>& SecurityHeaders();
// The page's policy: its one inline script and style by `nonce`, fetch to its own origin, the
// data: favicon; nothing else.
std::string PageCsp(const std::string& nonce);

}  // namespace pitmap::proc::live
