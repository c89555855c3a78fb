// SPDX-License-Identifier: MIT
#include "tools/sim/hil/faults.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace pitmap::sim::hil {
namespace {

constexpr const char* kValid =
    "garbage=N, crc=N, unplug=N, tcp-drop=N, jitter-ms=X, outage=A:B, unplug-s=X, none";

bool ParseInt(const std::string& s, int& out) {
    char* end = nullptr;
    const long v = std::strtol(s.c_str(), &end, 10);
    if (s.empty() || *end != '\0' || v < 0 || v > 1000) return false;
    out = static_cast<int>(v);
    return true;
}

bool ParseDouble(const std::string& s, double& out) {
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || *end != '\0' || !std::isfinite(v) || v < 0) return false;
    out = v;
    return true;
}

std::vector<double> Spread(int n, double begin, double end, double phase) {
    std::vector<double> t;
    if (n <= 0 || end <= begin) return t;
    const double step = (end - begin) / n;
    for (int i = 0; i < n; ++i) t.push_back(begin + step * (i + phase));
    return t;
}

}  // namespace

void FaultPlan::Schedule(double duration_s, double settle_s, double tail_s) {
    const double begin = std::min(settle_s, 0.3 * duration_s);
    const double end = std::max(begin, duration_s - std::min(tail_s, 0.3 * duration_s));
    garbage_times_s = Spread(garbage_bursts, begin, end, 0.20);
    crc_times_s = Spread(crc_errors, begin, end, 0.45);
    unplug_times_s = Spread(unplugs, begin, end, 0.70);
    tcp_drop_times_s = Spread(tcp_drops, begin, end, 0.90);
}

Expected<FaultPlan> ParseFaults(const std::string& text) {
    FaultPlan plan;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        if (item.empty() || item == "none") continue;
        const auto eq = item.find('=');
        const std::string key = item.substr(0, eq);
        const std::string value = eq == std::string::npos ? "" : item.substr(eq + 1);
        bool good = eq != std::string::npos;
        if (key == "garbage") {
            good = good && ParseInt(value, plan.garbage_bursts);
        } else if (key == "crc") {
            good = good && ParseInt(value, plan.crc_errors);
        } else if (key == "unplug") {
            good = good && ParseInt(value, plan.unplugs);
        } else if (key == "tcp-drop") {
            good = good && ParseInt(value, plan.tcp_drops);
        } else if (key == "jitter-ms") {
            good = good && ParseDouble(value, plan.jitter_ms) && plan.jitter_ms <= 1000;
        } else if (key == "unplug-s") {
            good = good && ParseDouble(value, plan.unplug_s) && plan.unplug_s > 0.05 &&
                   plan.unplug_s <= 60;
        } else if (key == "outage") {
            const auto colon = value.find(':');
            double a = 0, b = 0;
            good = good && colon != std::string::npos && ParseDouble(value.substr(0, colon), a) &&
                   ParseDouble(value.substr(colon + 1), b) && a < b;
            if (good) {
                plan.outage_s.push_back(a);
                plan.outage_s.push_back(b);
            }
        } else {
            return Error{"--faults: unknown fault '" + key + "' (valid: " + kValid + ")"};
        }
        if (!good) {
            return Error{"--faults: bad value in '" + item + "' (valid: " + kValid + ")"};
        }
    }
    return plan;
}

}  // namespace pitmap::sim::hil
