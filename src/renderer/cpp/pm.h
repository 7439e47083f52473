// pm: photon mapping with volumetric photons, and the per-iteration estimator
// that sppm runs with shrinking radii.
//   Jensen 1996, "Global illumination using photon maps";
//   Jensen & Christensen 1998, "Efficient simulation of light transport in scenes
//     with participating media using photon maps";
//   Jarosz, Zwicker & Jensen 2008, "The beam radiance estimate for volumetric photon mapping";
//   (sppm) Hachisuka, Ogaki & Jensen 2008, "Progressive photon mapping";
//   (sppm) Hachisuka & Jensen 2009, "Stochastic progressive photon mapping";
//   Knaus & Zwicker 2011, "Progressive photon mapping: a probabilistic approach".
//
// One iteration, each step a pass (passes.h):
//   1. light paths (subpaths.h, traced first): surface photons = vertices on non-delta
//      surfaces, volume photons = real collisions in media; `begin` puts each set in a
//      kd-tree (photon_map.h), takes the iteration's radii from their schedules and starts
//      spp_per_iteration camera paths per pixel (box filter);
//   2. camera paths: `shade` (repeated with `next_rays`) follows each through null
//      boundaries and specular surfaces (dielectric, mirror) to the first
//      non-specular surface:
//        - in a medium, the beam radiance estimate along the traced segment
//          [0, t_hit] (Jarosz et al. 2008, eq. 15 with a constant 2D kernel):
//            L += sum_photons Tr(0, t_p) phase(w_p, -d) power_p / (N pi r_v^2)
//          over the photons of that medium whose disc of radius r_v the segment
//          crosses, r_v the medium's own; near the surfaces the segment starts and ends on,
//          the disc lies parallel to them instead (boundary_kernels.h: it no longer reaches
//          past them, where there are no photons); the path then carries Tr(0, t_hit) to
//          the surface;
//        - emitters hit (directly or through specular chains) add Le;
//        - at a diffuse surface, the density estimate (Jensen 1996, eq. 6):
//            L += sum_photons f(w_p, w_o) power_p / (N pi r_s^2)
//          over surface photons within r_s whose surface faces the same way.
//   3. `end`: each path's radiance to its pixel, in path order.
// A photon of depth k gathered after s specular camera bounces makes a path
// of s + k real scattering events: it is used iff DepthLimit::allows(s + k) (Mitsuba).
// The estimate is biased by the kernel (blur over r); pm keeps r fixed (alpha = 1), sppm
// shrinks it per iteration (radius_schedule.h) so the mean of the iterations converges.
// Both kernels are 2D discs (the surface estimate, and the beam radiance estimate around
// the camera ray), so both schedules have dimension 2. Each medium has a schedule of its own
// (the same alpha): the default radii differ by medium (methods/pm.py).
// The pilot pass (set_pilot), run once before the first iteration with photons and camera
// paths of its own, estimates nothing: each camera-path vertex at a diffuse surface and each
// medium segment records the distance within which its k nearest photons lie (the photons it
// would gather, kth_nearest_* of photon_map.h); methods/pm.py derives the default radii from
// them.
#pragma once

#include <memory>

#include "boundary_kernels.h"
#include "camera_path.h"  // camera samples and wave bookkeeping shared with pt and ppb
#include "radius_schedule.h"
#include "subpaths.h"
#include "photon_map.h"
#include "pilot.h"
#include "surface_photons.h"

namespace pgi {

struct GatherPath {
    Vec3 pos, dir;
    double lead = 0;  // medium behind pos (start_path_at)
    RGB throughput{1.0};
    RGB radiance{0.0};
    int64_t pixel = 0;
    int specular = 0;   // real (specular) scattering events so far
    int medium = -1;
    int null_crossings = 0;
    int start_triangle = -1;  // the surface the current ray left (-1: the camera)
    bool alive = false;
    Sampler rng;
};

struct PhotonGatherStats {
    uint64_t surface_photons = 0, volume_photons = 0;
    uint64_t surface_lookups = 0, volume_lookups = 0;  // photons accepted by queries
};

class PhotonMapping : public SingleLane<PhotonMapping>, public NoShadowRays {
public:
    static constexpr int kDimension = 2;  // of both kernels (see above)

    // radius schedules: r_1 and alpha of the surface and of the volume estimate (every medium's
    // until set_volume_radius).
    PhotonMapping(std::shared_ptr<const Scene> scene, std::shared_ptr<const LightPaths> light_paths, int max_depth,
                  uint64_t seed, int spp_per_iteration, int threads, double surface_radius, double surface_alpha,
                  double volume_radius, double volume_alpha);

    size_t capacity() const { return paths_.size(); }
    // Pass 1: photon maps of this iteration's light paths, its radii, its camera paths.
    void begin(int64_t iteration);
    // Pass 2 (with next_rays, repeated): estimates along and at the end of each traced ray.
    size_t next_rays(const RayBuffers &out);
    size_t shade(const Hits &hits);
    // Pass 3: path radiance to the film, in path order.
    void end();

    // r_1 of the surface schedule, or of one medium's.
    void set_surface_radius(double radius);
    void set_volume_radius(int medium, double radius);
    const RadiusSchedule &surface_schedule() const { return surface_schedule_; }
    const RadiusSchedule &volume_schedule(int medium) const;
    int medium_count() const { return int(volume_schedules_.size()); }

    // Turns this kernel into a pilot (above), or back (both k 0): see RadiusPilot::set (pilot.h),
    // the k nearest photons. After a pass, pilot_result(-1) holds the surfaces', pilot_result(m)
    // medium m's.
    void set_pilot(size_t surface_neighbours, size_t volume_neighbours, double extent_fraction, int64_t path_stride) {
        pilot_.set(surface_neighbours, volume_neighbours, extent_fraction, path_stride);
    }
    bool pilot() const { return pilot_.on(); }
    const PilotResult &pilot_result(int kernel) const { return pilot_.result(kernel); }
    const Film &film() const { return film_; }
    const Scene &scene() const { return *scene_; }
    const PhotonGatherStats &stats() const { return stats_; }
    uint64_t density_lookups() const { return medium_stats_.density_lookups; }

private:
    RGB beam_estimate(const GatherPath &p, double t_hit, const BoundaryPlane &exit, double radius, Sampler rng,
                      MediumStats &ms, uint64_t &accepted) const;
    double pilot_segment(const GatherPath &p, double t_hit, Sampler rng, double &free_path) const;
    double pilot_surface(const GatherPath &p, int tri, const Vec3 &x) const;
    RGB surface_estimate(const GatherPath &p, int tri, const Vec3 &x, double radius, uint64_t &accepted) const;

    std::shared_ptr<const Scene> scene_;
    std::shared_ptr<const LightPaths> light_paths_;
    DepthLimit depth_;
    uint64_t seed_;
    int spp_per_iteration_, threads_;
    RadiusSchedule surface_schedule_;
    std::vector<RadiusSchedule> volume_schedules_;  // by medium
    double surface_radius_ = 0;                     // this iteration's
    std::vector<double> volume_radii_;              // this iteration's, by medium
    RadiusPilot pilot_{"pm"};
    std::vector<GatherPath> paths_;
    std::vector<int32_t> active_;
    // This iteration's photons (of the light paths of iteration photons_iteration_).
    int64_t photons_iteration_ = -1;
    std::vector<PathVertex> surface_photons_, volume_photons_;
    PointTree surface_tree_, volume_tree_;
    double inv_light_paths_ = 0;
    Film film_;
    PhotonGatherStats stats_;
    MediumStats medium_stats_;
};

}  // namespace pgi
