// SPDX-License-Identifier: MIT
// Neighbour search over a fixed array of 3D points: a nanoflann k-d tree behind a small class
// that both calibration and SLAM use. The points are not copied; they must outlive the index
// and not move while it exists. `Index` is the integer the tree keeps per point (its
// permutation): std::uint32_t halves it for arrays of fewer than 2^32 points (SLAM's sections,
// held for the whole survey), with the same tree and the same answers (the build and the
// searches compare the points, never their indices).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <nanoflann.hpp>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/result.hpp"

namespace pitmap::proc::reg {

template <class Scalar, class Index = std::size_t>
class PointIndex {
public:
    using Point = Eigen::Matrix<Scalar, 3, 1>;
    // (index into the points, squared distance)
    using Hit = std::pair<std::size_t, Scalar>;

    PointIndex(const Point* points, std::size_t count)
        : view_{points, CheckedCount(count)},
          tree_(3, view_, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize)) {}  // builds
    PointIndex(const PointIndex&) = delete;
    PointIndex& operator=(const PointIndex&) = delete;

    std::size_t size() const { return view_.n; }
    // Bytes the index holds beside the points: its permutation and its nodes.
    std::size_t memory_bytes() const {
        return tree_.vAcc.capacity() * sizeof(typename decltype(tree_.vAcc)::value_type) +
               tree_.pool.usedMemory + tree_.pool.wastedMemory;
    }
    const Point& point(std::size_t i) const { return view_.pts[i]; }

    // The k nearest points (fewer if the index holds fewer); returns how many were found.
    std::size_t Nearest(const Point& q, std::size_t k, std::size_t* idx, Scalar* d2) const {
        if constexpr (std::is_same_v<Index, std::size_t>) {
            return tree_.knnSearch(q.data(), k, idx, d2);
        } else {
            constexpr std::size_t kOnStack = 64;
            Index local[kOnStack];
            std::vector<Index> heap;
            Index* found = local;
            if (k > kOnStack) {
                heap.resize(k);
                found = heap.data();
            }
            const std::size_t n = tree_.knnSearch(q.data(), k, found, d2);
            for (std::size_t i = 0; i < n; ++i) idx[i] = found[i];
            return n;
        }
    }
    // The nearest point strictly closer than sqrt(bound2): true and its index and squared
    // distance, or false. The bound prunes the descent, so that asking a tree whose points all
    // lie beyond it costs a few node visits (a k = 1 search with no bound walks down to the
    // nearest point however far it is). Ties go to the point the descent meets first, as in
    // Nearest(q, 1).
    bool NearestWithin(const Point& q, Scalar bound2, std::size_t* idx, Scalar* d2) const {
        Closest r(bound2);
        tree_.findNeighbors(r, q.data(), nanoflann::SearchParams());
        if (!r.found) return false;
        *idx = r.index;
        *d2 = r.dist;
        return true;
    }
    // NearestWithin among the points whose index `accept(i)` admits (a time or pass filter):
    // the rejected points cost a distance each but never shrink the bound.
    template <class Accept>
    bool NearestWithinIf(
        const Point& q, Scalar bound2, const Accept& accept, std::size_t* idx, Scalar* d2) const {
        ClosestIf<Accept> r(bound2, accept);
        tree_.findNeighbors(r, q.data(), nanoflann::SearchParams());
        if (!r.found) return false;
        *idx = r.index;
        *d2 = r.dist;
        return true;
    }
    // Every point within sqrt(radius2) of q, unsorted; `hits` is cleared first.
    void WithinRadius(const Point& q, Scalar radius2, std::vector<Hit>& hits) const {
        hits.clear();
        if constexpr (std::is_same_v<Index, std::size_t>) {
            tree_.radiusSearch(q.data(), radius2, hits, nanoflann::SearchParams(32, 0, false));
        } else {
            Within r(radius2, hits);  // the radius search's own test, unsorted as above
            tree_.findNeighbors(r, q.data(), nanoflann::SearchParams(32, 0, false));
        }
    }

    // The positions t = (p - c) . n along the unit axis n of every point p in the cylinder about
    // c of radius `radius` and |t| <= half_length, unsorted, into `along` (cleared first);
    // `hits` is scratch. The same points as a sphere search of sqrt(radius^2 + half_length^2)
    // filtered to the cylinder, which visits every point of that sphere (for a 0.5 m x 4 m
    // cylinder across a surface, 13 m^2 of it to keep 0.8 m^2): here the axis is cut into
    // slabs of about `radius` and each slab's sphere searched (radius sqrt(radius^2 +
    // (1.01 x its half-thickness)^2)), a point kept by the slab its t falls in.
    void WithinCylinder(const Point& c,
                        const Point& n,
                        Scalar radius,
                        Scalar half_length,
                        std::vector<Hit>& hits,
                        std::vector<Scalar>& along) const {
        along.clear();
        const Scalar r2 = radius * radius;
        const int slabs = std::max(1, static_cast<int>(std::ceil(half_length / (radius / 2))));
        const Scalar half_slab = half_length / static_cast<Scalar>(slabs);
        const Scalar reach = Scalar(1.01) * half_slab;
        for (int k = 0; k < slabs; ++k) {
            const Scalar tk = -half_length + (2 * k + 1) * half_slab;
            WithinRadius(c + tk * n, r2 + reach * reach, hits);
            for (const auto& [i, d2] : hits) {
                const Point v = point(i) - c;
                const Scalar t = v.dot(n);
                if (std::abs(t) > half_length) continue;
                if ((v - t * n).squaredNorm() > r2) continue;
                const int owner =
                    std::clamp(static_cast<int>(std::floor((t + half_length) / (2 * half_slab))),
                               0,
                               slabs - 1);
                if (owner == k) along.push_back(t);
            }
        }
    }

private:
    static constexpr std::size_t kLeafSize = 16;
    static std::size_t CheckedCount(std::size_t count) {
        PITMAP_CHECK(count <= std::numeric_limits<Index>::max(),
                     "PointIndex: more points than its index type holds");
        return count;
    }
    // Every point strictly within the radius, as nanoflann's RadiusResultSet keeps them.
    struct Within {
        Within(Scalar r2, std::vector<Hit>& h) : radius2(r2), hits(h) {}
        Scalar worstDist() const { return radius2; }
        bool full() const { return true; }
        bool addPoint(Scalar d, Index i) {
            if (d < radius2) hits.emplace_back(std::size_t{i}, d);
            return true;
        }
        Scalar radius2;
        std::vector<Hit>& hits;
    };
    // nanoflann result set keeping the closest point under a bound that shrinks as it is met.
    struct Closest {
        explicit Closest(Scalar bound) : dist(bound) {}
        Scalar worstDist() const { return dist; }
        bool full() const { return true; }
        bool addPoint(Scalar d, std::size_t i) {
            if (d < dist) {
                dist = d;
                index = i;
                found = true;
            }
            return true;
        }
        Scalar dist;
        std::size_t index = 0;
        bool found = false;
    };
    template <class Accept>
    struct ClosestIf : Closest {
        ClosestIf(Scalar bound, const Accept& a) : Closest(bound), accept(a) {}
        bool addPoint(Scalar d, std::size_t i) {
            if (d < this->dist && accept(i)) {
                this->dist = d;
                this->index = i;
                this->found = true;
            }
            return true;
        }
        const Accept& accept;
    };
    struct View {
        const Point* pts = nullptr;
        std::size_t n = 0;
        std::size_t kdtree_get_point_count() const { return n; }
        Scalar kdtree_get_pt(std::size_t i, std::size_t d) const {
            return pts[i][static_cast<Eigen::Index>(d)];
        }
        template <class Box>
        bool kdtree_get_bbox(Box& /*box*/) const {
            return false;
        }
    };
    using Tree = nanoflann::
        KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<Scalar, View>, View, 3, Index>;
    View view_;
    Tree tree_;
};

using PointIndex3f = PointIndex<float>;
using PointIndex3d = PointIndex<double>;

}  // namespace pitmap::proc::reg
