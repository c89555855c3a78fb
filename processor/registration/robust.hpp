// SPDX-License-Identifier: MIT
// Robust kernels for iteratively reweighted least squares, shared by calibration and SLAM.
#pragma once

namespace pitmap::proc::reg {

enum class RobustKernel { kNone, kHuber, kCauchy };

// IRLS weight of a residual with whitened norm s (= sqrt(r^T Info r)); c is the kernel width
// in the same whitened units. kNone: 1; Huber: min(1, c / s); Cauchy: 1 / (1 + (s / c)^2).
double RobustWeight(RobustKernel kernel, double whitened_norm, double c);

// The cost rho(s) whose IRLS weight RobustWeight is (rho'(s) / (2 s)): kNone: s^2; Huber: s^2
// up to c, then 2 c s - c^2; Cauchy: c^2 log(1 + (s / c)^2).
double RobustCost(RobustKernel kernel, double whitened_norm, double c);

}  // namespace pitmap::proc::reg
