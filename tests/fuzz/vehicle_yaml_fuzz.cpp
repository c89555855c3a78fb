// SPDX-License-Identifier: MIT
// libFuzzer target for the vehicle file parser (common/vehicle.hpp). A parse either fails with
// a message naming the input, or gives a description whose written form parses back to the same
// values (the writer and the reader agree on everything the reader accepts).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "common/vehicle.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    const auto v = pitmap::ParseVehicleYaml(text, "fuzz.yaml");
    if (!v) {
        if (v.error().message.rfind("fuzz.yaml", 0) != 0) std::abort();
        return 0;
    }
    const auto again = pitmap::ParseVehicleYaml(pitmap::FormatVehicleYaml(*v), "written");
    if (!again || again->sonar_lever_arm_m != v->sonar_lever_arm_m ||
        again->boresight_deg != v->boresight_deg || again->connector != v->connector ||
        again->orientation != v->orientation || again->tilt_deg != v->tilt_deg ||
        again->sonar_clock_offset_s != v->sonar_clock_offset_s || again->name != v->name ||
        again->gnss_antenna_lever_arms_m != v->gnss_antenna_lever_arms_m ||
        again->uncertainty.has_value() != v->uncertainty.has_value() ||
        (v->uncertainty &&
         (again->uncertainty->range_sigma_m != v->uncertainty->range_sigma_m ||
          again->uncertainty->latency_sigma_s != v->uncertainty->latency_sigma_s))) {
        std::abort();
    }
    return 0;
}
