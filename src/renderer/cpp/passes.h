// The iteration protocol every native kernel follows, and the small pieces that let a kernel
// follow it without writing what it does not need.
//
// One iteration of a method is a short sequence of kernels (light paths, then a gather, ...).
// Each kernel runs the same passes, driven from Python by one driver (renderer/wavefront.py),
// with Embree tracing every batch of rays in between:
//
//   begin(iteration)               the iteration's setup: paths started, maps or beams built
//                                  from the kernels before it; no ray written yet
//   on each of lanes() lanes (lane(i)), each on a thread of its own:
//     resolve shadow rays          whatever begin queued (lt's connections to the camera)
//     while (n = next_rays(rays))  the rays of the paths in flight (the first call: their
//                                  first rays); trace them, then
//       if (shade(hits))           what each ray found; returns the shadow rays it queued
//         resolve shadow rays
//   end()                          the iteration's results to the film, in a fixed order
//
// where "resolve shadow rays" is: while (m = shadow_rays(rays)) trace them, then
// resolve_shadows(hits) (closest hits) or, when the scene has no null boundary, the cheaper
// occlusion query. A lane's rays fit in capacity() slots, its shadow rays in shadow_slots()
// (the slots opened so far; the driver grows its buffer to that before writing).
//
// Most kernels are one lane whose passes run on all their threads (OpenMP); pt streams its
// paths through one single-threaded lane per thread. Each kernel is bound to Python by one
// helper (bindings.h, bind_kernel), so every kernel offers the same vocabulary.
#pragma once

#include <stdexcept>
#include <string>

#include "wavefront.h"

namespace pgi {

// A kernel that is its own (only) lane: lanes() = 1, lane(0) = the kernel.
template <typename Kernel>
class SingleLane {
public:
    using Lane = Kernel;
    int lanes() const { return 1; }
    Kernel &lane(int i) {
        if (i != 0) throw std::out_of_range("no lane " + std::to_string(i) + ": this kernel has one");
        return static_cast<Kernel &>(*this);
    }
};

// A kernel that queues no shadow rays.
class NoShadowRays {
public:
    size_t shadow_slots() const { return 0; }
    size_t shadow_rays(const RayBuffers &) { return 0; }
    void resolve_shadows(const Hits &hits) {
        if (hits.count) throw std::logic_error("resolve_shadows: this kernel queues no shadow rays");
    }
};

// A kernel that traces no rays of its own paths (it only connects, through shadow rays).
class NoExtensionRays {
public:
    size_t capacity() const { return 0; }
    size_t next_rays(const RayBuffers &) { return 0; }
    size_t shade(const Hits &hits) {
        if (hits.count) throw std::logic_error("shade: this kernel traces no rays of its own");
        return 0;
    }
};

}  // namespace pgi
