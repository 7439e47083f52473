// kd-tree build for photon queries (see photon_map.h).
#include "photon_map.h"

#include <algorithm>
#include <numeric>
#include <stdexcept>

namespace pgi {

void PointTree::build(const std::vector<Vec3> &points) {
    if (points.size() >= (size_t(1) << 32) - 1) throw std::length_error("photon map: too many points");
    order_.resize(points.size());
    std::iota(order_.begin(), order_.end(), 0u);
    points_ = points;
    nodes_.clear();
    if (points.empty()) return;
    nodes_.reserve(2 * (points.size() / kLeafSize + 1));
    nodes_.emplace_back();
    build_node(0, 0, uint32_t(points.size()), 0);
    // Points in tree order, so that leaves read contiguous memory.
    std::vector<Vec3> sorted(points.size());
    for (size_t i = 0; i < points.size(); ++i) sorted[i] = points[order_[i]];
    points_.swap(sorted);
}

void PointTree::build_node(int node, uint32_t begin, uint32_t end, int depth) {
    Node n;
    n.begin = begin;
    n.end = end;
    for (int a = 0; a < 3; ++a) {
        n.lo[a] = kInf;
        n.hi[a] = -kInf;
    }
    for (uint32_t i = begin; i < end; ++i) {
        const Vec3 &p = points_[order_[i]];
        for (int a = 0; a < 3; ++a) {
            n.lo[a] = std::min(n.lo[a], p[a]);
            n.hi[a] = std::max(n.hi[a], p[a]);
        }
    }
    // Depth is bounded so that the query stacks cannot overflow: median splits
    // halve the count, so depth stays near log2(n / leaf) anyway.
    if (end - begin <= uint32_t(kLeafSize) || depth >= kMaxStack / 2 - 2) {
        nodes_[node] = n;
        return;
    }
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (n.hi[a] - n.lo[a] > n.hi[axis] - n.lo[axis]) axis = a;
    uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                     [&](uint32_t a, uint32_t b) {
                         double pa = points_[a][axis], pb = points_[b][axis];
                         return pa < pb || (pa == pb && a < b);
                     });
    int left = int(nodes_.size());
    n.left = left;
    nodes_[node] = n;
    nodes_.emplace_back();
    nodes_.emplace_back();
    build_node(left, begin, mid, depth + 1);
    build_node(left + 1, mid, end, depth + 1);
}

}  // namespace pgi
