// SPDX-License-Identifier: MIT
// The HTTP rules on crafted bytes and headers: where a request ends (split at every offset,
// leading empty lines, bodies, smuggling attempts, over-long headers), which Host names pass,
// which writes pass, which client ids pass, and the policy the page gets.
#include "processor/live/http_rules.hpp"

#include <gtest/gtest.h>

#include <string>

namespace pitmap::proc::live {
namespace {

using Kind = RequestFrame::Kind;

TEST(FrameRequest, ACompleteGetAtEveryPrefixLength) {
    const std::string req = "GET /api/status HTTP/1.1\r\nHost: localhost\r\n\r\n";
    for (std::size_t n = 0; n < req.size(); ++n) {
        EXPECT_EQ(FrameRequest(req.substr(0, n), 8192, 0).kind, Kind::kNeedMore) << n;
    }
    const RequestFrame f = FrameRequest(req + "GET /next", 8192, 0);
    EXPECT_EQ(f.kind, Kind::kComplete);
    EXPECT_EQ(f.total_bytes, req.size());  // a pipelined request after it is left alone
}

TEST(FrameRequest, ABodyByContentLengthAndLeadingEmptyLines) {
    const std::string head = "POST /api/snapshot HTTP/1.1\r\ncontent-LENGTH:  5 \r\n\r\n";
    EXPECT_EQ(FrameRequest(head + "abcd", 8192, 100).kind, Kind::kNeedMore);
    const RequestFrame f = FrameRequest("\r\n\r\n" + head + "abcdeXYZ", 8192, 100);
    ASSERT_EQ(f.kind, Kind::kComplete);
    EXPECT_EQ(f.skipped, 4u);
    EXPECT_EQ(f.header_bytes, head.size());
    EXPECT_EQ(f.total_bytes, head.size() + 5);
}

TEST(FrameRequest, RefusesWhatItCannotFrameSafely) {
    const auto status = [](const std::string& bytes) {
        const RequestFrame f = FrameRequest(bytes, 1024, 100);
        return f.kind == Kind::kError ? f.status : 0;
    };
    EXPECT_EQ(status("POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n"), 501);
    EXPECT_EQ(status("POST / HTTP/1.1\r\nContent-Length: 1\r\nContent-Length: 2\r\n\r\n"), 400);
    EXPECT_EQ(status("POST / HTTP/1.1\r\nContent-Length: -1\r\n\r\n"), 400);
    EXPECT_EQ(status("POST / HTTP/1.1\r\nContent-Length: 1e3\r\n\r\n"), 400);
    EXPECT_EQ(status("POST / HTTP/1.1\r\nContent-Length: 101\r\n\r\n"), 413);
    EXPECT_EQ(status("GET / HTTP/1.1\r\nX: a\r\n folded\r\n\r\n"), 400);
    EXPECT_EQ(status("GET / HTTP/1.1\r\nno colon\r\n\r\n"), 400);
    // Over the header limit: refused before its end arrives, and after.
    EXPECT_EQ(status("GET / HTTP/1.1\r\nX: " + std::string(1100, 'a')), 431);
    EXPECT_EQ(status("GET / HTTP/1.1\r\nX: " + std::string(1100, 'a') + "\r\n\r\n"), 431);
    EXPECT_EQ(status("POST / HTTP/1.1\r\nContent-Length: 2\r\nContent-Length: 2\r\n\r\n"), 0);
}

TEST(HostName, NamesAddressesAndPorts) {
    EXPECT_EQ(HostName("LocalHost:8765"), "localhost");
    EXPECT_EQ(HostName("127.0.0.1"), "127.0.0.1");
    EXPECT_EQ(HostName("[::1]:80"), "[::1]");
    EXPECT_EQ(HostName("[::1]"), "[::1]");
    for (const char* bad : {"",
                            "::1",
                            "[::1",
                            "[::1]x",
                            "a:b:c",
                            "host:",
                            "host:x",
                            "a b",
                            "evil.example/x",
                            "[zz]",
                            "host:123456"}) {
        EXPECT_EQ(HostName(bad), "") << bad;
    }
}

TEST(HostAllowed, LoopbackTheBindAddressAndExtraNamesOnly) {
    const auto allowed = AllowedHosts("10.0.0.5", {"Vessel.local", "fd00::7"});
    for (const char* ok : {"localhost",
                           "localhost:8765",
                           "127.0.0.1:1",
                           "[::1]:8765",
                           "10.0.0.5:8080",
                           "vessel.local",
                           "[fd00::7]:8765"}) {
        EXPECT_TRUE(HostAllowed(ok, allowed)) << ok;
    }
    for (const char* bad : {"",
                            "evil.example",
                            "evil.example:8765",
                            "10.0.0.6",
                            "127.0.0.2",
                            "localhost.evil.example",
                            "[::2]"}) {
        EXPECT_FALSE(HostAllowed(bad, allowed)) << bad;
    }
}

TEST(CheckWriteRequest, TheTokenAndTheSameOrigin) {
    const std::string token = "0123456789abcdef";
    EXPECT_EQ(
        CheckWriteRequest({token, "http://127.0.0.1:8765", "same-origin", "127.0.0.1:8765"}, token),
        "");
    EXPECT_EQ(CheckWriteRequest({token, "", "", "127.0.0.1:8765"}, token), "");  // curl
    // A cross-origin form (text/plain) POST: no token, a foreign Origin.
    EXPECT_NE(CheckWriteRequest({"", "http://evil.example", "cross-site", "127.0.0.1:8765"}, token)
                  .find("cross-origin"),
              std::string::npos);
    // Even with the token (leaked somehow), another origin is refused.
    EXPECT_NE(CheckWriteRequest({token, "http://evil.example", "", "127.0.0.1:8765"}, token), "");
    EXPECT_NE(CheckWriteRequest({token, "null", "", "127.0.0.1:8765"}, token), "");
    EXPECT_NE(CheckWriteRequest({token, "", "same-site", "127.0.0.1:8765"}, token), "");
    // Same origin without the token, or a wrong one.
    EXPECT_NE(CheckWriteRequest({"", "http://127.0.0.1:8765", "", "127.0.0.1:8765"}, token)
                  .find(kTokenHeader),
              std::string::npos);
    EXPECT_NE(CheckWriteRequest({"0123456789abcdeX", "", "", "h"}, token), "");
    EXPECT_NE(CheckWriteRequest({"", "", "", "h"}, ""), "");  // no token configured: no writes
}

TEST(CheckClientParams, EveryClientValue) {
    EXPECT_EQ(CheckClientParams({}), "");
    EXPECT_EQ(CheckClientParams({{"client", "k3x_9-Z"}, {"since", "<x>"}}), "");
    EXPECT_NE(CheckClientParams({{"client", "<script>"}}), "");
    EXPECT_NE(CheckClientParams({{"client", std::string(42, 'a')}}), "");
    EXPECT_NE(CheckClientParams({{"client", "ok"}, {"client", "not ok"}}), "");
}

TEST(SecurityHeaders, DefaultAndPagePolicies) {
    bool csp = false;
    for (const auto& h : SecurityHeaders()) {
        if (std::string(h.name) == "Content-Security-Policy") {
            csp = true;
            EXPECT_NE(std::string(h.value).find("default-src 'none'"), std::string::npos);
            EXPECT_NE(std::string(h.value).find("frame-ancestors 'none'"), std::string::npos);
        }
    }
    EXPECT_TRUE(csp);
    const std::string page = PageCsp("abc");
    EXPECT_NE(page.find("script-src 'nonce-abc'"), std::string::npos);
    EXPECT_NE(page.find("connect-src 'self'"), std::string::npos);
    EXPECT_EQ(page.find("unsafe"), std::string::npos);
}

}  // namespace
}  // namespace pitmap::proc::live
