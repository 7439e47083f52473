#include "beams.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace pgi {

void BeamBvh::build(std::vector<Beam> beams, double radius, double max_piece_length) {
    radius_ = radius;
    beams_.clear();
    pieces_.clear();
    nodes_.clear();
    beams_.reserve(std::min(beams.size(), max_beams_));
    size_t skipped_over_bound = 0;
    for (Beam &b : beams) {
        if (!(b.length > 0) || is_black(b.power) || !std::isfinite(b.length)) continue;
        if (beams_.size() >= max_beams_) {
            ++skipped_over_bound;
            continue;
        }
        beams_.push_back(b);
    }
    truncated_ += skipped_over_bound;
    if (beams_.empty()) return;

    // Piece length: at most max_piece_length, longer if the pieces would exceed
    // their bound (kPiecesPerBeam on average).
    double total = 0;
    for (const Beam &b : beams_) total += b.length;
    double budget = double(kPiecesPerBeam) * double(beams_.size());
    piece_length_ = std::max(max_piece_length > 0 ? max_piece_length : kInf, total / budget);
    for (size_t i = 0; i < beams_.size(); ++i) {
        const Beam &b = beams_[i];
        int n = std::isfinite(piece_length_) ? std::max(1, int(std::ceil(b.length / piece_length_))) : 1;
        n = std::min<int>(n, 1 << 16);
        for (int k = 0; k < n; ++k) {
            double t0 = b.length * k / n, t1 = k + 1 == n ? b.length : b.length * (k + 1) / n;
            pieces_.push_back(Piece{b.origin, b.dir, t0, t1, k + 1 == n, int32_t(i)});
        }
    }

    // Boxes and centroids of the pieces.
    size_t np = pieces_.size();
    std::vector<Vec3> lo(np), hi(np), centre(np);
    for (size_t i = 0; i < np; ++i) {
        const Beam &b = beams_[pieces_[i].beam];
        Vec3 a = b.origin + b.dir * pieces_[i].t0, c = b.origin + b.dir * pieces_[i].t1;
        for (int k = 0; k < 3; ++k) {
            lo[i][k] = std::min(a[k], c[k]) - radius;
            hi[i][k] = std::max(a[k], c[k]) + radius;
        }
        centre[i] = (a + c) * 0.5;
    }
    std::vector<int32_t> order(np);
    std::iota(order.begin(), order.end(), 0);

    // Build with an explicit stack of (node index, begin, end).
    nodes_.reserve(2 * np / kLeafSize + 1);
    struct Task {
        int32_t node, begin, end;
    };
    std::vector<Task> tasks;
    nodes_.push_back(Node{});
    tasks.push_back({0, 0, int32_t(np)});
    while (!tasks.empty()) {
        Task t = tasks.back();
        tasks.pop_back();
        Vec3 blo(kInf), bhi(-kInf), clo(kInf), chi(-kInf);
        for (int32_t i = t.begin; i < t.end; ++i)
            for (int k = 0; k < 3; ++k) {
                int32_t p = order[i];
                blo[k] = std::min(blo[k], lo[p][k]);
                bhi[k] = std::max(bhi[k], hi[p][k]);
                clo[k] = std::min(clo[k], centre[p][k]);
                chi[k] = std::max(chi[k], centre[p][k]);
            }
        for (int k = 0; k < 3; ++k) {
            // float boxes halve the tree's memory traffic; rounding outwards keeps them conservative.
            nodes_[t.node].lo[k] = std::nextafter(float(blo[k]), -std::numeric_limits<float>::infinity());
            nodes_[t.node].hi[k] = std::nextafter(float(bhi[k]), std::numeric_limits<float>::infinity());
        }
        int32_t count = t.end - t.begin;
        Vec3 extent = chi - clo;
        int axis = extent.x > extent.y ? (extent.x > extent.z ? 0 : 2) : (extent.y > extent.z ? 1 : 2);
        if (count <= kLeafSize || !(extent[axis] > 0)) {
            nodes_[t.node].first = t.begin;
            nodes_[t.node].count = count;
            continue;
        }
        int32_t mid = t.begin + count / 2;
        std::nth_element(order.begin() + t.begin, order.begin() + mid, order.begin() + t.end,
                         [&](int32_t a, int32_t b) {
                             // Ties broken by index: the same tree on every machine.
                             return centre[a][axis] < centre[b][axis] ||
                                    (centre[a][axis] == centre[b][axis] && a < b);
                         });
        // The two children are allocated together: right = left + 1.
        int32_t left = int32_t(nodes_.size());
        int32_t right = left + 1;
        nodes_.push_back(Node{});
        nodes_.push_back(Node{});
        nodes_[t.node].first = left;
        nodes_[t.node].count = 0;
        tasks.push_back({right, mid, t.end});
        tasks.push_back({left, t.begin, mid});
    }
    // Reorder pieces so that leaves index contiguous ranges.
    std::vector<Piece> sorted(np);
    for (size_t i = 0; i < np; ++i) sorted[i] = pieces_[order[i]];
    pieces_.swap(sorted);
}

}  // namespace pgi
