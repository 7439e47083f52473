// The k smallest of the distances a search meets, within a bound: what the pilot's k-nearest
// queries keep (PointTree::kth_nearest_*, photon_map.h; BeamBvh::kth_nearest, beams.h).
#pragma once

#include <algorithm>
#include <vector>

#include "common.h"

namespace pgi {

// The k smallest values added so far (a max-heap), each below max_value when added.
class KSmallest {
public:
    KSmallest(size_t k, double max_value) : k_(k), max_(max_value) { heap_.reserve(k); }
    // What a value must stay below to be among the k smallest: the k-th so far, or max_value.
    double bound() const { return full() ? heap_.front() : max_; }
    void add(double value) {
        if (full()) {
            std::pop_heap(heap_.begin(), heap_.end());
            heap_.back() = value;
        } else {
            heap_.push_back(value);
        }
        std::push_heap(heap_.begin(), heap_.end());
    }
    // The k-th smallest (kInf: fewer than k added).
    double kth() const { return full() ? heap_.front() : kInf; }

private:
    bool full() const { return k_ > 0 && heap_.size() == k_; }
    size_t k_;
    double max_;
    std::vector<double> heap_;
};

}  // namespace pgi
