// Acceleration structure for photon queries: a kd-tree over points (median
// split on the widest axis, small leaves) with the bounding box of every node.
// It answers the two queries of photon mapping:
//   - sphere: every point within r of a position (surface density estimation,
//     Jensen 1996);
//   - ray: every point within r of a ray segment [0, tmax], i.e. every photon
//     disc of radius r (facing the ray) that the segment crosses (the beam
//     radiance estimate, Jarosz, Zwicker & Jensen 2008).
// Points are visited in a fixed order (tree order), so sums over a query are
// deterministic. The tree is built once per iteration and read by many threads.
// For the default radii (methods/pm.py), it also finds the distance within which the k
// nearest accepted points lie around a point or a segment (kth_nearest_*).
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "common.h"
#include "k_nearest.h"

namespace pgi {

class PointTree {
public:
    // Deterministic: the same tree whatever the thread count.
    void build(const std::vector<Vec3> &points, int threads = 1);
    size_t size() const { return points_.size(); }
    size_t node_count() const { return nodes_.size(); }

    // visit(index, distance^2) for every point with |p - c| < r.
    template <typename Visit>
    void query_sphere(const Vec3 &c, double r, Visit &&visit) const {
        const double r2 = r * r;
        walk([&](const Node &n) { return box_distance2(n, c) >= r2; }, kLeftFirst, [&](uint32_t i) {
            Vec3 d = points_[i] - c;
            double q = dot(d, d);
            if (q < r2) visit(order_[i], q);
        });
    }

    // visit(index, t, distance^2) for every point whose projection on the ray
    // (o, unit d) lies in [0, tmax] at distance < r from it.
    template <typename Visit>
    void query_ray(const Vec3 &o, const Vec3 &d, double tmax, double r, Visit &&visit) const {
        const double r2 = r * r;
        const Vec3 inv(1 / d.x, 1 / d.y, 1 / d.z);
        auto missed = [&](const Node &n) { return !ray_meets_box(o, d, inv, n.lo, n.hi, tmax, r); };  // grown by r
        walk(missed, kLeftFirst, [&](uint32_t i) {
            Vec3 v = points_[i] - o;
            double t = dot(v, d);
            if (t < 0 || t > tmax) return;
            double q = dot(v, v) - t * t;
            if (q < r2) visit(order_[i], t, std::max(0.0, q));
        });
    }

    // The distance from c within which lie the k nearest points that `accept(index)` takes,
    // searching no farther than max_radius: kInf if fewer than k lie within it.
    template <typename Accept>
    double kth_nearest_to_point(const Vec3 &c, size_t k, double max_radius, Accept &&accept) const {
        auto beyond = [&](const Node &n, double bound2) { return box_distance2(n, c) >= bound2; };
        // The nearer child is visited first: the bound shrinks sooner.
        auto nearer_first = [&](const Node &n) {
            return box_distance2(nodes_[n.left], c) < box_distance2(nodes_[n.left + 1], c);
        };
        auto distance2 = [&](const Vec3 &p) {
            Vec3 d = p - c;
            return dot(d, d);
        };
        return kth_nearest(k, max_radius, beyond, nearer_first, distance2, accept);
    }

    // The same around the segment [o, o + tmax d] (unit d): distances to the segment.
    template <typename Accept>
    double kth_nearest_to_segment(const Vec3 &o, const Vec3 &d, double tmax, size_t k, double max_radius,
                                  Accept &&accept) const {
        const Vec3 inv(1 / d.x, 1 / d.y, 1 / d.z);
        // A point within the bound of the segment lies in a box the segment meets, grown by it.
        auto beyond = [&](const Node &n, double bound2) {
            return !ray_meets_box(o, d, inv, n.lo, n.hi, tmax, std::sqrt(bound2));
        };
        auto distance2 = [&](const Vec3 &p) {
            Vec3 v = p - o;
            double t = std::clamp(dot(v, d), 0.0, tmax);
            Vec3 e = v - d * t;
            return dot(e, e);
        };
        return kth_nearest(k, max_radius, beyond, kLeftFirst, distance2, accept);
    }

private:
    struct Node;
    static double box_distance2(const Node &n, const Vec3 &c) {
        double d2 = 0;
        for (int a = 0; a < 3; ++a) {
            double e = std::max({n.lo[a] - c[a], 0.0, c[a] - n.hi[a]});
            d2 += e * e;
        }
        return d2;
    }
    static constexpr auto kLeftFirst = [](const Node &) { return true; };

    // Depth first from the root over the nodes that skip(node) does not prune, the left child
    // first where left_first(node): point(i) for each point of the leaves reached (i in tree order).
    template <typename Skip, typename LeftFirst, typename Point>
    void walk(Skip &&skip, LeftFirst &&left_first, Point &&point) const {
        if (nodes_.empty()) return;
        int stack[kMaxStack];
        int top = 0;
        stack[top++] = 0;
        while (top) {
            const Node &n = nodes_[stack[--top]];
            if (skip(n)) continue;
            if (n.left < 0) {
                for (uint32_t i = n.begin; i < n.end; ++i) point(i);
                continue;
            }
            int first = n.left, second = n.left + 1;
            if (!left_first(n)) std::swap(first, second);
            stack[top++] = second;
            stack[top++] = first;
        }
    }

    // The k-nearest search of both kth_nearest_* queries: a walk that skips the nodes beyond
    // the squared distance still sought (skip(node, bound2)), keeping the k smallest
    // distance2(point) of the accepted points; their k-th, or kInf.
    template <typename Skip, typename LeftFirst, typename Distance2, typename Accept>
    double kth_nearest(size_t k, double max_radius, Skip &&skip, LeftFirst &&left_first, Distance2 &&distance2,
                       Accept &&accept) const {
        if (nodes_.empty() || k == 0) return kInf;
        KSmallest kth(k, max_radius * max_radius);  // squared distances
        walk([&](const Node &n) { return skip(n, kth.bound()); }, left_first, [&](uint32_t i) {
            double q = distance2(points_[i]);
            if (q < kth.bound() && accept(order_[i])) kth.add(q);
        });
        return std::sqrt(kth.kth());
    }

    static constexpr int kLeafSize = 8;
    static constexpr int kMaxStack = 128;
    struct Node {
        double lo[3], hi[3];
        uint32_t begin = 0, end = 0;
        int left = -1;  // children at left and left + 1 (heap layout: 2 node + 1); -1 for a leaf
    };
    void build_node(int node, uint32_t begin, uint32_t end, int depth);
    // Subtrees above this depth are built as parallel tasks.
    static constexpr int kTaskDepth = 4;

    struct Item {
        Vec3 point;
        uint32_t index;
    };
    std::vector<Item> items_;      // build only
    std::vector<Node> nodes_;
    std::vector<Vec3> points_;     // in tree order
    std::vector<uint32_t> order_;  // tree order -> input index
};

}  // namespace pgi
