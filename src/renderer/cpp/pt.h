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

#include "wavefront.h"

namespace pgi {

struct CameraPath {
    Vec3 pos, dir;
    RGB throughput{1.0};
    RGB radiance{0.0};   // everything this path has gathered so far
    Vec3 prev_pos;       // last real scattering vertex (for the light pdf in MIS)
    double prev_pdf = 0; // solid-angle pdf of the direction sampled there
    double eta2 = 1;     // product of squared IOR ratios crossed (for Russian roulette)
    int64_t pixel = 0;
    int depth = 0;       // real scattering events so far
    int medium = -1;
    int null_crossings = 0;
    bool prev_delta = true;
    bool alive = false;
    Sampler rng;
};

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

private:
    void scatter_in_medium(CameraPath &p, size_t slot, const Vec3 &x);
    void scatter_on_surface(CameraPath &p, size_t slot, int tri, const Vec3 &x);
    void queue_shadow(CameraPath &p, size_t slot, const LightSample &ls, const RGB &f, double pdf_dir,
                      const Vec3 &origin, int medium);
    bool russian_roulette(CameraPath &p);

    std::shared_ptr<const Scene> scene_;
    int max_depth_, rr_depth_;
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
