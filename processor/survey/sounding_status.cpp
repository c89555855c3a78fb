// SPDX-License-Identifier: MIT
#include "processor/survey/sounding_status.hpp"

namespace pitmap::proc::survey {

std::string_view ToString(SoundingStatus s) {
    switch (s) {
        case SoundingStatus::kAccepted:
            return "accepted";
        case SoundingStatus::kNoDetection:
            return "no_detection";
        case SoundingStatus::kRangeGate:
            return "range_gate";
        case SoundingStatus::kSpike:
            return "spike";
        case SoundingStatus::kRefraction:
            return "refraction";
        case SoundingStatus::kSurfaceFilter:
            return "surface_filter";
        case SoundingStatus::kFreeSpace:
            return "free_space";
        case SoundingStatus::kMultipath:
            return "multipath";
        case SoundingStatus::kCluster:
            return "cluster";
        case SoundingStatus::kManual:
            return "manual";
        case SoundingStatus::kProfile:
            return "profile";
    }
    return "unknown";
}

}  // namespace pitmap::proc::survey
