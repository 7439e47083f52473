// kd-tree build for photon queries (see photon_map.h).
#include "photon_map.h"

#include <omp.h>

#include <algorithm>
#include <numeric>
#include <stdexcept>

namespace pgi {


void PointTree::build(const std::vector<Vec3> &points, int threads) {
    if (points.size() >= (size_t(1) << 32) - 1) throw std::length_error("photon map: too many points");
    nodes_.clear();
    order_.clear();
    points_.clear();
    if (points.empty()) return;
    // Splits move (point, index) items themselves: contiguous memory, unlike an index array.
    items_.resize(points.size());
    for (size_t i = 0; i < points.size(); ++i) items_[i] = {points[i], uint32_t(i)};
    // Median splits keep the tree balanced, so a heap layout (children of node i at
    // 2i + 1 and 2i + 2) fits in 2^(D+1) - 1 nodes, D the depth at which nodes are leaves;
    // subtrees can then be built in parallel without sharing an allocator.
    int depth = 0;
    for (size_t n = points.size(); n > size_t(kLeafSize) && depth < kMaxStack / 2 - 2; n = (n + 1) / 2) ++depth;
    nodes_.resize((size_t(2) << depth) - 1);
#pragma omp parallel num_threads(std::max(1, threads))
#pragma omp single
    build_node(0, 0, uint32_t(points.size()), 0);
    // Points in tree order, so that leaves read contiguous memory.
    points_.resize(items_.size());
    order_.resize(items_.size());
    for (size_t i = 0; i < items_.size(); ++i) {
        points_[i] = items_[i].point;
        order_[i] = items_[i].index;
    }
    items_.clear();
    items_.shrink_to_fit();
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
        const Vec3 &p = items_[i].point;
        n.lo[0] = std::min(n.lo[0], p.x);
        n.hi[0] = std::max(n.hi[0], p.x);
        n.lo[1] = std::min(n.lo[1], p.y);
        n.hi[1] = std::max(n.hi[1], p.y);
        n.lo[2] = std::min(n.lo[2], p.z);
        n.hi[2] = std::max(n.hi[2], p.z);
    }
    if (end - begin <= uint32_t(kLeafSize) || size_t(2 * node + 2) >= nodes_.size()) {
        nodes_[node] = n;
        return;
    }
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (n.hi[a] - n.lo[a] > n.hi[axis] - n.lo[axis]) axis = a;
    uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(items_.begin() + begin, items_.begin() + mid, items_.begin() + end,
                     [axis](const Item &a, const Item &b) {
                         double pa = axis == 0 ? a.point.x : (axis == 1 ? a.point.y : a.point.z);
                         double pb = axis == 0 ? b.point.x : (axis == 1 ? b.point.y : b.point.z);
                         return pa < pb || (pa == pb && a.index < b.index);
                     });
    n.left = 2 * node + 1;
    nodes_[node] = n;
    if (depth < kTaskDepth) {
#pragma omp task
        build_node(2 * node + 1, begin, mid, depth + 1);
#pragma omp task
        build_node(2 * node + 2, mid, end, depth + 1);
#pragma omp taskwait
    } else {
        build_node(2 * node + 1, begin, mid, depth + 1);
        build_node(2 * node + 2, mid, end, depth + 1);
    }
}

}  // namespace pgi
