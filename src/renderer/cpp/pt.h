// pt: volumetric path tracing with next-event estimation and multiple
// importance sampling on surfaces and in media.
//   Kajiya 1986, "The rendering equation";
//   Veach 1997, "Robust Monte Carlo methods for light transport simulation", ch. 9 (MIS);
//   Pharr, Jakob & Humphreys, "Physically Based Rendering", 4th ed., ch. 14 (volumetric paths).
//
// One wave traces `spp_per_wave` camera paths for every pixel. Python drives
// the passes (see renderer/methods/pt.py); each pass here is a parallel loop
// over paths whose random numbers depend only on (seed, sample, pixel).
// Depth is counted as Mitsuba's volpath does: real scattering events only,
// null-boundary crossings and null collisions are free.
#pragma once

#include <memory>

#include "camera_path.h"

namespace pgi {

class PathTracer {
public:
    PathTracer(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed,
               int spp_per_wave, int threads);

    size_t capacity() const { return paths_.size(); }
    // Pass 1: camera rays for wave `iteration` into `out`; returns the count.
    size_t begin_wave(int64_t iteration, const RayBuffers &out);
    // Pass 2: for each traced ray, sample the medium, add emission, scatter and
    // queue a shadow ray. Returns the number of queued shadow rays.
    size_t shade(const Hits &hits);
    // Pass 3 (repeated): write pending shadow segments; returns their count.
    size_t shadow_rays(const RayBuffers &out) { return shadow_.compact_and_write(out, threads_); }
    void resolve_shadows(const Hits &hits);
    // Pass 4: extension rays of the paths still alive.
    size_t next_rays(const RayBuffers &out);
    // Pass 5: add the wave's paths to the film, in path order.
    void end_wave();

    const Film &film() const { return film_; }
    uint64_t density_lookups() const { return stats_.density_lookups; }
    uint64_t media_segments() const { return stats_.segments; }
    uint64_t paths_traced() const { return paths_traced_; }
    int threads() const { return threads_; }
    const Scene &scene() const { return *scene_; }

private:
    std::shared_ptr<const Scene> scene_;
    CameraPathSteps steps_;
    int max_depth_;
    uint64_t seed_;
    int spp_per_wave_, threads_;
    std::vector<CameraPath> paths_;
    std::vector<int32_t> active_;
    ShadowQueue shadow_;
    Film film_;
    MediumStats stats_;
    uint64_t paths_traced_ = 0;
};

}  // namespace pgi
