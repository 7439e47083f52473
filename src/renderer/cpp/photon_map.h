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
        if (nodes_.empty()) return;
        double r2 = r * r;
        int stack[kMaxStack];
        int top = 0;
        stack[top++] = 0;
        while (top) {
            const Node &n = nodes_[stack[--top]];
            double d2 = 0;
            for (int a = 0; a < 3; ++a) {
                double e = std::max({n.lo[a] - c[a], 0.0, c[a] - n.hi[a]});
                d2 += e * e;
            }
            if (d2 >= r2) continue;
            if (n.left < 0) {
                for (uint32_t i = n.begin; i < n.end; ++i) {
                    Vec3 d = points_[i] - c;
                    double q = dot(d, d);
                    if (q < r2) visit(order_[i], q);
                }
                continue;
            }
            stack[top++] = n.left + 1;
            stack[top++] = n.left;
        }
    }

    // visit(index, t, distance^2) for every point whose projection on the ray
    // (o, unit d) lies in [0, tmax] at distance < r from it.
    template <typename Visit>
    void query_ray(const Vec3 &o, const Vec3 &d, double tmax, double r, Visit &&visit) const {
        if (nodes_.empty()) return;
        double r2 = r * r;
        Vec3 inv(1 / d.x, 1 / d.y, 1 / d.z);
        int stack[kMaxStack];
        int top = 0;
        stack[top++] = 0;
        while (top) {
            const Node &n = nodes_[stack[--top]];
            if (!ray_meets_box(o, d, inv, n.lo, n.hi, tmax, r)) continue;  // the box grown by r
            if (n.left < 0) {
                for (uint32_t i = n.begin; i < n.end; ++i) {
                    Vec3 v = points_[i] - o;
                    double t = dot(v, d);
                    if (t < 0 || t > tmax) continue;
                    double q = dot(v, v) - t * t;
                    if (q < r2) visit(order_[i], t, std::max(0.0, q));
                }
                continue;
            }
            stack[top++] = n.left + 1;
            stack[top++] = n.left;
        }
    }

    // The distance from c within which lie the k nearest points that `accept(index)` takes,
    // searching no farther than max_radius: kInf if fewer than k lie within it.
    template <typename Accept>
    double kth_nearest_to_point(const Vec3 &c, size_t k, double max_radius, Accept &&accept) const {
        KthDistance kth(k, max_radius);
        if (nodes_.empty() || k == 0) return kth.result();
        int stack[kMaxStack];
        int top = 0;
        stack[top++] = 0;
        while (top) {
            const Node &n = nodes_[stack[--top]];
            if (box_distance2(n, c) >= kth.bound2()) continue;
            if (n.left < 0) {
                for (uint32_t i = n.begin; i < n.end; ++i) {
                    Vec3 d = points_[i] - c;
                    double q = dot(d, d);
                    if (q < kth.bound2() && accept(order_[i])) kth.add(q);
                }
                continue;
            }
            // The nearer child is visited first (pushed last): the bound shrinks sooner.
            int a = n.left, b = n.left + 1;
            if (box_distance2(nodes_[a], c) < box_distance2(nodes_[b], c)) std::swap(a, b);
            stack[top++] = a;
            stack[top++] = b;
        }
        return kth.result();
    }

    // The same around the segment [o, o + tmax d] (unit d): distances to the segment.
    template <typename Accept>
    double kth_nearest_to_segment(const Vec3 &o, const Vec3 &d, double tmax, size_t k, double max_radius,
                                  Accept &&accept) const {
        KthDistance kth(k, max_radius);
        if (nodes_.empty() || k == 0) return kth.result();
        Vec3 inv(1 / d.x, 1 / d.y, 1 / d.z);
        int stack[kMaxStack];
        int top = 0;
        stack[top++] = 0;
        while (top) {
            const Node &n = nodes_[stack[--top]];
            // A point within the bound of the segment lies in a box the segment meets, grown by it.
            if (!ray_meets_box(o, d, inv, n.lo, n.hi, tmax, std::sqrt(kth.bound2()))) continue;
            if (n.left < 0) {
                for (uint32_t i = n.begin; i < n.end; ++i) {
                    Vec3 v = points_[i] - o;
                    double t = std::clamp(dot(v, d), 0.0, tmax);
                    Vec3 e = v - d * t;
                    double q = dot(e, e);
                    if (q < kth.bound2() && accept(order_[i])) kth.add(q);
                }
                continue;
            }
            stack[top++] = n.left + 1;
            stack[top++] = n.left;
        }
        return kth.result();
    }

private:
    // The k smallest squared distances seen so far (a max-heap), within max_radius.
    class KthDistance {
    public:
        KthDistance(size_t k, double max_radius) : k_(k), max2_(max_radius * max_radius) { heap_.reserve(k); }
        double bound2() const { return heap_.size() == k_ ? heap_.front() : max2_; }
        void add(double q) {
            if (heap_.size() == k_) {
                std::pop_heap(heap_.begin(), heap_.end());
                heap_.back() = q;
            } else {
                heap_.push_back(q);
            }
            std::push_heap(heap_.begin(), heap_.end());
        }
        double result() const { return heap_.size() == k_ && k_ > 0 ? std::sqrt(heap_.front()) : kInf; }

    private:
        size_t k_;
        double max2_;
        std::vector<double> heap_;
    };
    struct Node;
    static double box_distance2(const Node &n, const Vec3 &c) {
        double d2 = 0;
        for (int a = 0; a < 3; ++a) {
            double e = std::max({n.lo[a] - c[a], 0.0, c[a] - n.hi[a]});
            d2 += e * e;
        }
        return d2;
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
