// SPDX-License-Identifier: MIT
// PointIndex::WithinCylinder (processor/registration/neighbours.hpp): the same points as the
// sphere about the whole cylinder filtered to it, each once, on surfaces crossing it at any
// angle and with a second surface inside it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "processor/registration/neighbours.hpp"

namespace pitmap::proc::reg {
namespace {

using V = Eigen::Vector3d;

// The positions along n of the points in the cylinder, by the sphere about it (the reference).
std::vector<double> ByOneSphere(
    const std::vector<V>& pts, const V& c, const V& n, double radius, double half) {
    std::vector<double> out;
    for (const V& p : pts) {
        if ((p - c).squaredNorm() > radius * radius + half * half) continue;
        const V v = p - c;
        const double t = v.dot(n);
        if (std::abs(t) > half) continue;
        if ((v - t * n).squaredNorm() > radius * radius) continue;
        out.push_back(t);
    }
    std::sort(out.begin(), out.end());
    return out;
}

TEST(PointIndexCylinder, HoldsTheSamePointsAsTheSphereAboutItEachOnce) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-3.0, 3.0), w(-0.02, 0.02);
    std::vector<V> pts;
    // Two surfaces 1.2 m apart (a ridge's far face within the cylinder's reach), dense.
    for (int k = 0; k < 150000; ++k) {
        const double x = u(rng), y = u(rng);
        pts.emplace_back(x, y, 0.3 * x + w(rng));
        if (k % 3 == 0) pts.emplace_back(x, y, 0.3 * x - 1.2 + w(rng));
    }
    // Points on the slab boundaries along the axis (t at multiples of a slab) and at the ends.
    const V n0 = V(-0.3, 0.0, 1.0).normalized();
    for (int s = -8; s <= 8; ++s) pts.push_back(0.25 * s * n0 + V(0.0, 0.1, 0.0));
    const PointIndex<double> index(pts.data(), pts.size());
    std::vector<PointIndex<double>::Hit> hits;
    std::vector<double> along;
    std::uniform_real_distribution<double> angle(-1.0, 1.0);
    int cylinders = 0;
    for (int q = 0; q < 20; ++q) {
        const V n = q == 0 ? n0 : V(angle(rng), angle(rng), 1.0 + angle(rng)).normalized();
        const V c(0.5 * angle(rng), 0.5 * angle(rng), 0.0);
        for (const double radius : {0.5, 0.3, 1.0}) {
            const double half = 2.0;
            index.WithinCylinder(c, n, radius, half, hits, along);
            std::sort(along.begin(), along.end());
            const std::vector<double> ref = ByOneSphere(pts, c, n, radius, half);
            ASSERT_EQ(along, ref) << "cylinder " << q << " radius " << radius;
            ASSERT_FALSE(ref.empty());
            ++cylinders;
        }
    }
    EXPECT_EQ(cylinders, 60);
}

}  // namespace
}  // namespace pitmap::proc::reg
