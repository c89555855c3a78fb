// SPDX-License-Identifier: MIT
#include "processor/live/http_rules.hpp"

#include <algorithm>
#include <cctype>
#include <optional>

#include "processor/live/budget.hpp"

namespace pitmap::proc::live {

namespace {

std::string Lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

bool IEquals(std::string_view a, std::string_view b) {
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
               return std::tolower(static_cast<unsigned char>(x)) ==
                      std::tolower(static_cast<unsigned char>(y));
           });
}

std::string_view Trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
    return s;
}

bool AllDigits(std::string_view s) {
    return !s.empty() &&
           std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

RequestFrame Refuse(int status, std::string reason) {
    RequestFrame f;
    f.kind = RequestFrame::Kind::kError;
    f.status = status;
    f.reason = std::move(reason);
    return f;
}

// A comparison whose time does not depend on where the strings first differ: the token must
// not be learnable byte by byte from answer times.
bool SameSecret(const std::string& a, const std::string& b) {
    if (a.size() != b.size()) return false;
    unsigned char diff = 0;
    for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
    return diff == 0;
}

}  // namespace

RequestFrame FrameRequest(std::string_view bytes,
                          std::size_t max_header_bytes,
                          std::size_t max_body_bytes) {
    RequestFrame f;
    // Empty lines before a request line are ignored (a client may send one after a body).
    while (bytes.substr(0, 2) == "\r\n" || bytes.substr(0, 1) == "\n") {
        const std::size_t n = bytes[0] == '\r' ? 2 : 1;
        bytes.remove_prefix(n);
        f.skipped += n;
    }
    const std::size_t end = bytes.find("\r\n\r\n");
    if (end == std::string_view::npos) {
        if (bytes.size() > max_header_bytes)
            return Refuse(431,
                          "request header over " + std::to_string(max_header_bytes) + " bytes");
        return f;
    }
    f.header_bytes = end + 4;
    if (f.header_bytes > max_header_bytes)
        return Refuse(431, "request header over " + std::to_string(max_header_bytes) + " bytes");

    // The request line is httplib's to judge; here only the fields that say where it ends.
    std::string_view header = bytes.substr(0, end);
    const std::size_t first_eol = header.find("\r\n");
    std::string_view fields =
        first_eol == std::string_view::npos ? std::string_view() : header.substr(first_eol + 2);
    bool have_length = false;
    std::uint64_t length = 0;
    while (!fields.empty()) {
        const std::size_t eol = fields.find("\r\n");
        const std::string_view line = fields.substr(0, eol);
        fields = eol == std::string_view::npos ? std::string_view() : fields.substr(eol + 2);
        if (line.empty()) continue;
        if (line.front() == ' ' || line.front() == '\t')
            return Refuse(400, "folded header lines are not accepted");
        const std::size_t colon = line.find(':');
        if (colon == std::string_view::npos || colon == 0)
            return Refuse(400, "malformed header line");
        const std::string_view name = line.substr(0, colon);
        const std::string_view value = Trim(line.substr(colon + 1));
        if (IEquals(name, "transfer-encoding"))
            return Refuse(501, "request bodies with Transfer-Encoding are not accepted");
        if (IEquals(name, "content-length")) {
            // Two different lengths are a request smuggling attempt or a broken client.
            const auto v = AllDigits(value) && value.size() <= 18
                               ? std::optional<std::uint64_t>(std::stoull(std::string(value)))
                               : std::nullopt;
            if (!v || (have_length && *v != length)) return Refuse(400, "bad Content-Length");
            have_length = true;
            length = *v;
        }
    }
    if (length > max_body_bytes)
        return Refuse(413, "request body over " + std::to_string(max_body_bytes) + " bytes");
    f.total_bytes = f.header_bytes + static_cast<std::size_t>(length);
    if (bytes.size() >= f.total_bytes) f.kind = RequestFrame::Kind::kComplete;
    return f;
}

std::string HostName(std::string_view host_header) {
    const std::string h = Lower(Trim(host_header));
    std::string name;
    std::string_view port;
    if (!h.empty() && h.front() == '[') {
        const std::size_t close = h.find(']');
        if (close == std::string::npos) return {};
        name = h.substr(0, close + 1);
        const std::string_view rest = std::string_view(h).substr(close + 1);
        if (!rest.empty()) {
            if (rest.front() != ':') return {};
            port = rest.substr(1);
            if (!AllDigits(port)) return {};
        }
        const bool ok =
            name.size() > 2 && std::all_of(name.begin() + 1, name.end() - 1, [](char c) {
                return std::isxdigit(static_cast<unsigned char>(c)) || c == ':' || c == '.';
            });
        return ok ? name : std::string();
    }
    const std::size_t colon = h.find(':');
    if (colon != std::string::npos) {
        if (h.find(':', colon + 1) != std::string::npos) return {};  // bare IPv6: not a Host
        port = std::string_view(h).substr(colon + 1);
        if (!AllDigits(port) || port.size() > 5) return {};
        name = h.substr(0, colon);
    } else {
        name = h;
    }
    const bool ok = !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '-' || c == '_';
    });
    return ok ? name : std::string();
}

bool HostAllowed(std::string_view host_header, const std::vector<std::string>& allowed) {
    const std::string name = HostName(host_header);
    return !name.empty() && std::find(allowed.begin(), allowed.end(), name) != allowed.end();
}

std::vector<std::string> AllowedHosts(const std::string& bind_address,
                                      const std::vector<std::string>& extra) {
    std::vector<std::string> out = {"localhost", "127.0.0.1", "[::1]"};
    const auto add = [&out](const std::string& a) {
        std::string n = Lower(Trim(a));
        if (n.find(':') != std::string::npos && n.front() != '[') n = "[" + n + "]";
        if (!n.empty() && std::find(out.begin(), out.end(), n) == out.end()) out.push_back(n);
    };
    add(bind_address);
    for (const auto& e : extra) add(e);
    return out;
}

std::string CheckWriteRequest(const WriteRequestHeaders& h, const std::string& token) {
    if (!h.origin.empty()) {
        const std::string origin = Lower(h.origin), host = Lower(Trim(h.host));
        if (host.empty() || (origin != "http://" + host && origin != "https://" + host))
            return "cross-origin request refused (Origin " + h.origin + " is not this server)";
    }
    if (!h.sec_fetch_site.empty() && h.sec_fetch_site != "same-origin")
        return "cross-site request refused (Sec-Fetch-Site: " + h.sec_fetch_site + ")";
    if (token.empty() || !SameSecret(h.token, token))
        return std::string("a POST needs the page's token in the ") + kTokenHeader +
               " header (reload the page)";
    return {};
}

std::string CheckClientParams(const std::multimap<std::string, std::string>& params) {
    const auto [first, last] = params.equal_range("client");
    for (auto it = first; it != last; ++it) {
        LiveQuery q = ParseLiveQuery({{it->first, it->second}});
        if (!q.error.empty()) return q.error;
    }
    return {};
}

const std::vector<HeaderField>& SecurityHeaders() {
    static const std::vector<HeaderField> kHeaders = {
        {"Content-Security-Policy",
         "default-src 'none'; frame-ancestors 'none'; base-uri 'none'; form-action 'none'"},
        {"X-Content-Type-Options", "nosniff"},
        {"X-Frame-Options", "DENY"},
        {"Referrer-Policy", "no-referrer"},
        // Another site's page cannot even embed the JSON as a no-cors resource.
        {"Cross-Origin-Resource-Policy", "same-origin"},
    };
    return kHeaders;
}

std::string PageCsp(const std::string& nonce) {
    return "default-src 'none'; script-src 'nonce-" + nonce + "'; style-src 'nonce-" + nonce +
           "'; connect-src 'self'; img-src data:; base-uri 'none'; form-action 'none'; "
           "frame-ancestors 'none'";
}

}  // namespace pitmap::proc::live
