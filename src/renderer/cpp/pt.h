// pt: volumetric path tracing with next-event estimation and multiple importance sampling
// on surfaces and in media.
//   Kajiya 1986, "The rendering equation";
//   Veach 1997, "Robust Monte Carlo methods for light transport simulation", ch. 9 (MIS);
//   Pharr, Jakob & Humphreys, "Physically Based Rendering", 4th ed., ch. 14 (volumetric paths).
//
// The estimator. A camera path x_0 (the camera), x_1, x_2, ... is sampled vertex by vertex: a
// box-filtered position in the pixel, then at each step a free flight through the current
// medium and, at a real scattering vertex, a direction by the BSDF or the phase function.
// Its throughput before vertex x_k is
//   beta_k = prod_{i<k} [ flight weight to x_{i+1} ] * [ f(x_i) |cos| / p_dir(x_i) ],
// where the flight weight is sigma_s T / p_flight at a collision and T / p_flight past a surface
// (medium.h, sample_free_flight: the albedo and 1 in grey media; with chromatic extinction the
// path's hero channel samples and the weight divides by the mean of the channels' path pdfs),
// and f |cos| / p_dir is the BSDF sample's weight (or 1 for the phase function, sampled
// exactly). At each real scattering vertex x_k the pixel estimate gains
//   next-event estimation:  beta_k f(x_k, y) L_e(y) G(x_k, y) T(x_k, y) / p_light(y) w_light
//   emission:               beta_{k+1} L_e(x_{k+1}) w_dir   (the emitter the sampled direction
//                                                            reaches; also x_1 seen directly)
// with power-heuristic weights (beta = 2) between light sampling and direction sampling, both
// densities in solid angle at x_k: w_light = p_light^2 / (p_light^2 + p_dir^2), w_dir the
// complement; delta lights and delta BSDF events take weight 1. T of a shadow ray is the
// closed form in homogeneous media and the scene's transmittance estimator in grids. Depth
// follows Mitsuba's volpath: a path has fewer than max_depth real scattering events (null
// crossings and null collisions are free). After rr_depth events a path survives with
// probability min(max(beta) eta^2, 1) (or Mitsuba's cap of 0.95: wavefront.h,
// survive_roulette) and is divided by it.
//
// Step order: one iteration is a wave of `spp_per_wave` paths per pixel, run by the passes of
// passes.h on each lane:
//   begin       the wave's paths are numbered, none started (PathTracing::begin)
//   next_rays   paths that ended hand their radiance to the wave; their slots start the
//               wave's next paths (camera_path.h, start_camera_sample); every path in flight
//               writes its ray (PathTracingLane::next_rays)
//   shade       per traced ray (PathTracingLane::shade, with the steps of camera_path.h):
//               1. in a medium, the free flight to the hit (fly_through_medium); a collision
//                  counts an event and scatters there: NEE by the phase function, a phase-
//                  sampled direction, roulette (scatter_in_medium);
//               2. else at the surface hit: emission with MIS (reach_surface, add_emission);
//                  a null boundary is crossed for free (cross_null_boundary);
//               3. else a scattering surface: the event is counted (count_event), NEE unless
//                  the BSDF is delta (next_event_on_surface), then a BSDF-sampled direction and
//                  roulette (continue_by_bsdf);
//               each NEE queues one shadow ray.
//   shadow rays traced segment by segment through null boundaries, times the transmittance of
//               each medium crossed; an arrival adds its value to the path (wavefront.h,
//               ShadowQueue::resolve)
//   end         each path's radiance to its pixel, in path order (PathTracing::end)
//
// Streaming: each lane (one per thread, driven from Python by renderer/wavefront.py) keeps a
// fixed number of paths in flight, and as soon as a path ends its slot takes the next path of
// the wave that no lane has started yet. A lane's passes run on its own thread over its own
// slots, front to back: no thread team to wake between passes, no tail of near-empty batches
// until the wave runs out of paths, and a working set that stays small. Each path's random
// numbers depend only on (seed, sample, pixel) and each ended path's radiance is stored under
// its index, so the image is the same whatever the number of lanes or slots.
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
