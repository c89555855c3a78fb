// SPDX-License-Identifier: MIT
// libFuzzer target for what pitmap-live reads from outside: the page's query parameters
// (processor/live/budget.hpp ParseLiveQuery, the client id that keys the byte budgets), LCM
// events on the daemon's channels (processor/live/session.hpp OnEvent), followed by every JSON
// document the server sends, and the bytes of an HTTP request (processor/live/http_rules.hpp:
// FrameRequest, the Host and write checks). The first byte picks the mode: odd the query, 2
// mod 4 HTTP, else events. Invariants: nothing throws, a query without an error holds values
// in range, the JSON documents serialise (non-UTF-8 text from the wire is replaced), a framed
// request lies inside the bytes and frames the same on its own.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <string>
#include <string_view>

#include "lcmtypes/log/channels.hpp"
#include "processor/live/budget.hpp"
#include "processor/live/http_rules.hpp"
#include "processor/live/session.hpp"

namespace {

void Check(bool condition) {
    if (!condition) std::abort();
}

namespace ll = pitmap::lcmlog;
namespace live = pitmap::proc::live;

void FuzzQuery(const std::uint8_t* data, std::size_t size) {
    // "k=v&k=v..." split by hand, as the HTTP server's parser hands them over.
    std::multimap<std::string, std::string> params;
    std::string text(reinterpret_cast<const char*>(data), size);
    std::size_t at = 0;
    while (at <= text.size()) {
        std::size_t end = text.find('&', at);
        if (end == std::string::npos) end = text.size();
        const std::string pair = text.substr(at, end - at);
        const std::size_t eq = pair.find('=');
        params.emplace(pair.substr(0, eq), eq == std::string::npos ? "" : pair.substr(eq + 1));
        at = end + 1;
    }
    const live::LiveQuery q = live::ParseLiveQuery(params);
    if (q.error.empty()) {
        Check(q.since <= static_cast<std::uint64_t>(INT64_MAX));
        Check(q.max_bytes >= -1 && q.max_bytes <= INT32_MAX);
        Check(q.client.size() <= live::kMaxClientIdLength);
        for (char c : q.client) {
            Check((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                  c == '_' || c == '-');
        }
    }
    // Every key a page may send reaches the budgets' keying: bounded whatever the bytes.
    live::ClientBudgets budgets(1000, 1.0, 4);
    for (const auto& [key, value] : params) {
        const live::LiveQuery one = live::ParseLiveQuery({{"client", value}});
        if (one.error.empty()) budgets.Spend(one.client, 10, 1);
    }
    Check(budgets.tracked() <= 4);
}

void FuzzEvents(const std::uint8_t* data, std::size_t size) {
    static const std::string kChannels[] = {
        std::string(ll::kChannelInsPva) + "NOVATEL",
        std::string(ll::kChannelInsStdDev) + "NOVATEL",
        std::string(ll::kChannelGnssPosition) + "NOVATEL",
        std::string(ll::kChannelMultibeamPing) + "DELTAT",
        std::string(ll::kChannelClockSync),
        std::string(ll::kChannelDaemonStatus),
        "\xff\xfe not utf-8",
    };
    live::LiveConfig config;
    config.process_interval_s = 0;
    live::LiveSession session(config, {}, false);
    // Events: [channel byte][length u16 LE][bytes], repeated.
    std::size_t at = 0;
    std::int64_t wall = 1'781'500'000'000'000;
    while (at + 3 <= size) {
        const std::string& ch = kChannels[data[at] % std::size(kChannels)];
        std::size_t len = data[at + 1] | (static_cast<std::size_t>(data[at + 2]) << 8);
        at += 3;
        len = std::min(len, size - at);
        session.OnEvent(ch, data + at, len, wall);
        at += len;
        wall += 100'000;
        session.Tick(wall);
    }
    session.Tick(wall, true);
    const auto dump = [](const nlohmann::json& j) {
        return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    };
    Check(!dump(session.StatusJson(wall)).empty());
    Check(!dump(session.AlarmsJson()).empty());
    Check(!dump(session.TilesJson(0, 20'000)).empty());
    Check(!dump(session.SoundingsJson(0, 20'000)).empty());
}

void FuzzHttp(const std::uint8_t* data, std::size_t size) {
    using Kind = live::RequestFrame::Kind;
    const std::string_view bytes(reinterpret_cast<const char*>(data), size);
    const live::RequestFrame f = live::FrameRequest(bytes, 1024, 256);
    Check(f.skipped <= size);
    if (f.kind == Kind::kComplete) {
        Check(f.header_bytes <= f.total_bytes && f.skipped + f.total_bytes <= size);
        Check(f.header_bytes <= 1024 && f.total_bytes - f.header_bytes <= 256);
        // What the front hands on, framed again: the same request, whole.
        const live::RequestFrame again =
            live::FrameRequest(bytes.substr(f.skipped, f.total_bytes), 1024, 256);
        Check(again.kind == Kind::kComplete && again.skipped == 0 &&
              again.total_bytes == f.total_bytes);
    } else if (f.kind == Kind::kError) {
        Check(f.status >= 400 && f.status < 600 && !f.reason.empty());
    }
    // A Host that parses is allowed once its name is listed; the write check never throws.
    const std::string host(bytes.substr(0, std::min<std::size_t>(size, 300)));
    const std::string name = live::HostName(host);
    if (!name.empty()) Check(live::HostAllowed(host, {name}));
    (void)live::CheckWriteRequest({host, host, host, host}, "0123456789abcdef");
    (void)live::CheckClientParams({{"client", host}});
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    if (data[0] & 1) {
        FuzzQuery(data + 1, size - 1);
    } else if (data[0] % 4 == 2) {
        FuzzHttp(data + 1, size - 1);
    } else {
        FuzzEvents(data + 1, size - 1);
    }
    return 0;
}
