#include "beams.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pgi {

void BeamBvh::build(std::vector<Beam> beams, std::vector<double> radii, double max_piece_length) {
    if (radii.empty()) radii.push_back(0.0);
    radii_ = std::move(radii);
    beams_.clear();
    pieces_.clear();
    nodes_.clear();
    beams_.reserve(std::min(beams.size(), max_beams_));
    size_t skipped_over_bound = 0;
    for (Beam &b : beams) {
        if (!std::isfinite(b.length)) {
            // A light path that left the scene inside a medium (a grid no shape encloses):
            // its flux is real but no finite beam holds it. Counted, not hidden.
            ++escaped_;
            continue;
        }
        if (!(b.length > 0) || is_black(b.power)) continue;
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

    // Boxes and centroids of the pieces, sorted in place (no index indirection:
    // the build streams through memory).
    struct Item {
        float lo[3], hi[3], c[3];
        int32_t piece;
    };
    size_t np = pieces_.size();
    std::vector<Item> items(np);
    for (size_t i = 0; i < np; ++i) {
        const Piece &p = pieces_[i];
        Vec3 a = p.origin + p.dir * p.t0, c = p.origin + p.dir * p.t1;
        const double radius = this->radius(beams_[size_t(p.beam)].medium);
        Item &it = items[i];
        for (int k = 0; k < 3; ++k) {
            it.lo[k] = float(std::min(a[k], c[k]) - radius);
            it.hi[k] = float(std::max(a[k], c[k]) + radius);
            it.c[k] = float(0.5 * (a[k] + c[k]));
        }
        it.piece = int32_t(i);
    }
    const float kUp = std::numeric_limits<float>::infinity();

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
        float blo[3] = {kUp, kUp, kUp}, bhi[3] = {-kUp, -kUp, -kUp};
        float clo[3] = {kUp, kUp, kUp}, chi[3] = {-kUp, -kUp, -kUp};
        for (int32_t i = t.begin; i < t.end; ++i) {
            const Item &it = items[i];
            for (int k = 0; k < 3; ++k) {
                blo[k] = std::min(blo[k], it.lo[k]);
                bhi[k] = std::max(bhi[k], it.hi[k]);
                clo[k] = std::min(clo[k], it.c[k]);
                chi[k] = std::max(chi[k], it.c[k]);
            }
        }
        for (int k = 0; k < 3; ++k) {
            // Rounding outwards keeps the float boxes conservative.
            nodes_[t.node].lo[k] = std::nextafter(blo[k], -kUp);
            nodes_[t.node].hi[k] = std::nextafter(bhi[k], kUp);
        }
        int32_t count = t.end - t.begin;
        float ex = chi[0] - clo[0], ey = chi[1] - clo[1], ez = chi[2] - clo[2];
        int axis = ex > ey ? (ex > ez ? 0 : 2) : (ey > ez ? 1 : 2);
        if (count <= kLeafSize || !(chi[axis] > clo[axis])) {
            nodes_[t.node].first = t.begin;
            nodes_[t.node].count = count;
            continue;
        }
        int32_t mid = t.begin + count / 2;
        std::nth_element(items.begin() + t.begin, items.begin() + mid, items.begin() + t.end,
                         [axis](const Item &a, const Item &b) {
                             // Ties broken by piece index: the same tree on every machine.
                             return a.c[axis] < b.c[axis] || (a.c[axis] == b.c[axis] && a.piece < b.piece);
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
    for (size_t i = 0; i < np; ++i) sorted[i] = pieces_[items[i].piece];
    pieces_.swap(sorted);
}

}  // namespace pgi
