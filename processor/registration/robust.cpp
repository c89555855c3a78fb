// SPDX-License-Identifier: MIT
#include "processor/registration/robust.hpp"

#include <cmath>

namespace pitmap::proc::reg {

double RobustWeight(RobustKernel kernel, double whitened_norm, double c) {
    switch (kernel) {
        case RobustKernel::kNone:
            return 1.0;
        case RobustKernel::kHuber:
            return whitened_norm <= c ? 1.0 : c / whitened_norm;
        case RobustKernel::kCauchy: {
            const double u = whitened_norm / c;
            return 1.0 / (1.0 + u * u);
        }
    }
    return 1.0;
}

double RobustCost(RobustKernel kernel, double whitened_norm, double c) {
    const double s = whitened_norm;
    switch (kernel) {
        case RobustKernel::kNone:
            return s * s;
        case RobustKernel::kHuber:
            return s <= c ? s * s : 2.0 * c * s - c * c;
        case RobustKernel::kCauchy:
            return c * c * std::log1p((s / c) * (s / c));
    }
    return s * s;
}

}  // namespace pitmap::proc::reg
