// pt: volumetric path tracing with next-event estimation and multiple
// importance sampling on surfaces and in media.
//   Kajiya 1986, "The rendering equation";
//   Veach 1997, "Robust Monte Carlo methods for light transport simulation", ch. 9 (MIS);
//   Pharr, Jakob & Humphreys, "Physically Based Rendering", 4th ed., ch. 14 (volumetric paths).
//
// One wave traces `spp_per_wave` camera paths for every pixel. The wave is streamed
// through lanes: each lane (one per thread, driven from Python; see
// renderer/methods/pt.py) keeps a fixed number of paths in flight, and as soon as a
// path ends its slot takes the next path of the wave that no lane has started yet. A
// lane's passes run on its own thread over its own slots, front to back: no thread
// team to wake between passes, no tail of near-empty batches until the wave runs out
// of paths, and a working set that stays small. Each path's random numbers depend
// only on (seed, sample, pixel) and each ended path's radiance is stored under its
// index, so the image is the same whatever the number of lanes or slots.
// Depth is counted as Mitsuba's volpath does: real scattering events only,
// null-boundary crossings and null collisions are free.
#pragma once

#include <atomic>
#include <memory>

#include "camera_path.h"
#include "passes.h"

namespace pgi {

class PathTracing;

// One lane: its slots of paths in flight and its shadow-ray queue. Its passes follow the
// iteration protocol (passes.h) and must be called from one thread.
class PathTracingLane {
public:
    PathTracingLane(PathTracing &owner, size_t slots);

    size_t capacity() const { return slots_.size(); }
    size_t shadow_slots() const { return slots_.size(); }

    // Retires the paths that ended (their radiance to the wave), gives their slots the
    // wave's next paths, and writes the rays of the paths in flight; returns their count.
    // The first call of a wave fills every slot.
    size_t next_rays(const RayBuffers &out);
    // For each traced ray, sample the medium, add emission, scatter and queue a shadow
    // ray. Returns the number of queued shadow rays.
    size_t shade(const Hits &hits);
    // Write pending shadow segments; returns their count.
    size_t shadow_rays(const RayBuffers &out) { return shadow_.compact_and_write(out, 1); }
    void resolve_shadows(const Hits &hits);
    const Scene &scene() const;

private:
    friend class PathTracing;
    void reset();  // a new wave: every slot empty

    PathTracing &owner_;
    std::vector<CameraPath> slots_;
    std::vector<int64_t> path_of_slot_;  // the wave's path index in each slot, -1 if none
    std::vector<int32_t> active_;        // slots in flight, in the order of the ray batch
    ShadowQueue shadow_;
    MediumStats stats_;
    int64_t claimed_ = 0, claimed_end_ = 0;  // paths this lane claimed and has not started
};

class PathTracing {
public:
    using Lane = PathTracingLane;
    PathTracing(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed, int spp_per_wave,
                int lanes, int slots_per_lane);

    int lanes() const { return int(lanes_.size()); }
    PathTracingLane &lane(int i);
    // Pass 1: a new wave (iteration `iteration`); the lanes then trace it.
    void begin(int64_t iteration);
    // Last pass: add the wave's paths to the film, in path order.
    void end();
    const Scene &scene() const { return *scene_; }

    const Film &film() const { return film_; }
    uint64_t density_lookups() const { return stats_.density_lookups; }
    uint64_t media_segments() const { return stats_.segments; }

private:
    friend class PathTracingLane;
    // Claims up to `count` of the wave's paths not started yet: [first, first + n).
    int64_t claim(int64_t count, int64_t &n);

    std::shared_ptr<const Scene> scene_;
    CameraPathSteps steps_;
    DepthLimit depth_;
    uint64_t seed_;
    int spp_per_wave_;
    int64_t wave_paths_ = 0, iteration_ = 0;
    std::atomic<int64_t> next_path_{0};
    std::vector<RGB> radiance_;  // each path of the wave, stored when it ends
    std::vector<std::unique_ptr<PathTracingLane>> lanes_;
    Film film_;
    MediumStats stats_;
};

}  // namespace pgi
