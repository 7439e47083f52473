// The pilot pass of the gathering kernels of pm, sppm (pm.h) and ppb (ppb.h): run once before
// the first iteration, it estimates nothing; each query a kernel would make (a camera segment in a
// medium, a camera-path vertex on a diffuse surface) records the distance within which its k
// nearest photons (beams) lie, and methods/radii.py derives the default radii from them.
// RadiusPilot holds what a pass is asked (k by kind of query, the search bound, the paths
// sampled), what it records per hit of a shade pass, and its results by kernel.
#pragma once

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "common.h"

namespace pgi {

// What a pilot pass measures for one kernel (the surfaces, or one medium): the distance within
// which each query's k nearest lie (kInf: fewer than k within the search bound), and the
// bounding-sphere radius of what the kernel could gather (0: nothing).
struct PilotResult {
    std::vector<double> distances;
    std::vector<double> free_paths;  // of the segment queries: 1 / sigma_t where their flights ended
    double extent = 0;
};

// The box around the points added; its radius is half its diagonal (0: no point).
struct BoundingBox {
    Vec3 lo{kInf}, hi{-kInf};
    bool empty = true;
    void add(const Vec3 &p) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
        empty = false;
    }
    double radius() const { return empty ? 0.0 : 0.5 * length(hi - lo); }
};

// A kernel's pilot. Kernels are numbered as methods/radii.py asks for them: -1 the surfaces,
// m >= 0 medium m (index 1 + kernel in the vectors below).
class RadiusPilot {
public:
    // A query that records nothing (none made, or no flight ended within its segment).
    static constexpr double kNoRecord = -1;

    // `method` names the kernel in error messages.
    explicit RadiusPilot(const char *method) : method_(method) {}

    // Turns the pilot on, or off (both k 0): queries of the camera paths whose index is a multiple
    // of path_stride look for their k nearest (0: that kind of query records nothing), no farther
    // than extent_fraction of the bounding radius of what their kernel could gather.
    void set(size_t surface_neighbours, size_t medium_neighbours, double extent_fraction, int64_t path_stride) {
        if (!(extent_fraction > 0))
            throw std::invalid_argument(method_ + " pilot: the extent fraction must be positive");
        on_ = surface_neighbours > 0 || medium_neighbours > 0;
        surface_k_ = surface_neighbours;
        medium_k_ = medium_neighbours;
        extent_fraction_ = extent_fraction;
        stride_ = std::max<int64_t>(1, path_stride);
    }
    // No surface query records anything (the pilot stays on for the media).
    void skip_surfaces() { surface_k_ = 0; }
    bool on() const { return on_; }
    size_t surface_neighbours() const { return surface_k_; }
    size_t medium_neighbours() const { return medium_k_; }

    // A pass starts: boxes[1 + kernel] bounds what each kernel could gather; results cleared.
    void begin(const std::vector<BoundingBox> &boxes) {
        results_.assign(boxes.size(), PilotResult{});
        max_radius_.assign(boxes.size(), 0.0);
        for (size_t k = 0; k < boxes.size(); ++k) {
            results_[k].extent = boxes[k].radius();
            max_radius_[k] = extent_fraction_ * results_[k].extent;
        }
    }
    // The camera paths of the pass: every path_stride-th of those started; the others stop.
    template <typename Path>
    void sample_paths(std::vector<Path> &paths, std::vector<int32_t> &active) const {
        std::vector<int32_t> sampled;
        for (int32_t i : active)
            if (i % stride_ == 0) sampled.push_back(i);
            else paths[size_t(i)].alive = false;
        active.swap(sampled);
    }
    // How far a query of `kernel` searches.
    double max_radius(int kernel) const { return max_radius_[size_t(kernel + 1)]; }
    const PilotResult &result(int kernel) const {
        if (kernel < -1 || kernel + 1 >= int(results_.size()))
            throw std::out_of_range(method_ + ": no pilot result for that kernel");
        return results_[size_t(kernel + 1)];
    }

    // A shade pass of `hits` rays: each hit records at most one segment query and one surface
    // query (in parallel, each hit its own), then close_hits adds them to the results.
    void open_hits(size_t hits) { hits_.assign(hits, HitRecord{}); }
    void record_segment(size_t hit, int medium, double distance, double free_path) {
        HitRecord &h = hits_[hit];
        h.medium = medium;
        h.segment = distance;
        h.free_path = free_path;
    }
    void record_surface(size_t hit, double distance) { hits_[hit].surface = distance; }
    // In hit order: the same results whatever the thread count.
    void close_hits() {
        for (const HitRecord &h : hits_) {
            if (h.segment != kNoRecord) {
                PilotResult &result = results_[size_t(h.medium) + 1];
                result.distances.push_back(h.segment);
                result.free_paths.push_back(h.free_path);
            }
            if (h.surface != kNoRecord) results_[0].distances.push_back(h.surface);
        }
    }

private:
    struct HitRecord {
        double segment = kNoRecord, surface = kNoRecord;
        double free_path = kNoRecord;  // the mean free path where the segment's flight ended
        int medium = -1;
    };
    std::string method_;
    bool on_ = false;
    size_t surface_k_ = 0, medium_k_ = 0;
    double extent_fraction_ = 0;
    int64_t stride_ = 1;
    std::vector<double> max_radius_;    // by kernel
    std::vector<PilotResult> results_;  // by kernel
    std::vector<HitRecord> hits_;       // of the current shade pass
};

}  // namespace pgi
