// SPDX-License-Identifier: MIT
// libFuzzer target for the acquisition daemon's YAML config loader
// (firmware_host/daemon/daemon_config.cpp), from a string. Any input gives a config and a list
// of problems; it never throws or crashes.
#include <cstddef>
#include <cstdint>
#include <string>

#include "firmware_host/daemon/daemon_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    const auto loaded = pitmap::acq::LoadDaemonConfigFromString(text, "fuzz.yaml");
    (void)loaded;
    return 0;
}
