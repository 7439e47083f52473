// ppb: progressive photon beams.
//   Jarosz, Nowrouzezahrai, Thomas, Sloan & Zwicker 2011, "Progressive photon
//   beams", ACM TOG 30(6) (SIGGRAPH Asia);
//   Jarosz, Nowrouzezahrai, Sadeghi & Jensen 2011, "A comprehensive theory of
//   volumetric radiance estimation using photon points and beams", ACM TOG 30(1)
//   (the beam x beam 1D estimator, "BB1D");
//   Knaus & Zwicker 2011, "Progressive photon mapping: a probabilistic approach"
//   (the radius schedule, with a 1D kernel: d = 1).
//
// One iteration: light paths from the shared tracer (subpaths.h) leave their
// medium segments as *short* photon beams (each ends at the collision the
// tracer sampled, or at the surface when none was); camera paths then walk
// from the camera through media without scattering there, and every medium
// segment they cross gathers the beams of the same medium with
//   L += T_cam(t) sigma_s(x) phase(theta) * power * T_beam(s) / P_beam(s)
//        * 1/(2r) / sin(theta) / N_light_paths                      (BB1D)
// where x is the closest point on the camera segment, s the distance along the
// beam, T/P the short-beam weight (subpaths.h), r this iteration's radius for the beam's
// medium (each medium has a schedule of its own). Near the surfaces a camera segment starts
// and ends on, the blur lies parallel to them instead of along the common perpendicular
// (boundary_kernels.h), so that it no longer reaches past them, where there are no beams.
// Camera transmittance: closed form in homogeneous media; in density grids a
// distance is sampled by delta tracking and only beams before it are gathered
// (the camera ray is a short query ray; weight 1 for gray extinction).
//
// Surfaces, with surface photons on (the default of methods/ppb.py): the
// camera path ends at its first diffuse surface D, whose outgoing radiance is
// emission + next-event estimation (light -> D directly, no MIS: nothing else
// samples it) + a density estimate of the photons that arrived at D after at
// least one scattering event (Jensen 1996; radius of a d = 2 schedule). This
// is how the progressive photon-beam papers treat surfaces, and it turns
// surface caustics (light -> glass -> D) from fireflies into a blur.
// Without surface photons, surfaces are path traced as in pt.h: emission with MIS, next-event
// estimation and BSDF sampling at diffuse surfaces, specular and null surfaces
// followed. Beams serve the camera path's media until it has bounced off
// `gather_diffuse_bounces` + 1 diffuse surfaces; from there on the path scatters
// in media itself (free flight, next-event estimation from the medium, phase
// sampling). So the path space splits by where the camera path's first medium
// vertex lies: before the (k+1)-th diffuse surface -> beams (every light-side
// prefix, any depth), otherwise (or none) -> path tracing; nothing is counted
// twice. A small k keeps the expensive beam queries to a few segments per
// pixel sample. Depth (Mitsuba's max_depth, DepthLimit): a beam gathered after s surface
// events on the camera side makes a path of beam.depth + 1 + s events.
// The pilot pass (set_pilot), run once before the first iteration with light paths of its
// own, estimates nothing: each camera segment that would gather beams records the distance
// within which its k nearest beams lie (BeamBvh::kth_nearest), and each surface-photon
// estimate that of its k nearest photons; methods/ppb.py derives the default radii from them.
#pragma once

#include <memory>

#include "beams.h"
#include "boundary_kernels.h"
#include "subpaths.h"
#include "photon_map.h"
#include "pilot.h"
#include "surface_photons.h"
#include "radius_schedule.h"
#include "camera_path.h"

namespace pgi {

// A camera path that gathers beams along its segments in media until its
// (gather_diffuse_bounces + 1)-th diffuse bounce, and is path traced after it.
struct BeamGatherPath : CameraPath {
    int diffuse_bounces = 0;
    int start_triangle = -1;  // the surface the current ray left (-1: the camera, a medium vertex)
    bool gathering = true;  // media are still estimated by beams (diffuse_bounces <= limit)
};

// Counts of one run (all iterations).
struct BeamStats {
    uint64_t photons = 0;         // surface photons stored
    uint64_t beams = 0;           // stored
    uint64_t beam_pairs = 0;      // camera-segment x beam pairs gathered
    uint64_t density_lookups = 0;
};

class ProgressivePhotonBeams : public SingleLane<ProgressivePhotonBeams> {
public:
    // radius: r_1 of the schedule r_i = r_1 i^(alpha - 1) (Knaus & Zwicker 2011, d = 1), every
    // medium's until set_beam_radius; max_piece_length: the longest piece of a beam in the BVH
    // (beams.h).
    ProgressivePhotonBeams(std::shared_ptr<const Scene> scene, std::shared_ptr<const LightPaths> light_paths,
                           int max_depth, int rr_depth, uint64_t seed, int spp_per_iteration, int threads,
                           size_t max_beams, double radius, double alpha, double max_piece_length,
                           int gather_diffuse_bounces);
    // Surface photons at the first diffuse surface (radius r_1 of a d = 2 schedule);
    // off (radius 0) leaves surfaces to path tracing.
    void set_surface_photons(double radius, double alpha);
    // r_1 of one medium's beam schedule.
    void set_beam_radius(int medium, double radius);
    // Turns this kernel into a pilot (above), or back (both k 0): see RadiusPilot::set (pilot.h),
    // the k nearest beams (surface photons; none without them). After a pass, pilot_result(-1)
    // holds the surface photons', pilot_result(m) medium m's.
    void set_pilot(size_t surface_neighbours, size_t beam_neighbours, double extent_fraction, int64_t path_stride);
    bool pilot() const { return pilot_.on(); }
    const PilotResult &pilot_result(int kernel) const { return pilot_.result(kernel); }

    size_t capacity() const { return paths_.size(); }
    size_t shadow_slots() const { return shadow_.opened(); }
    // Pass 1: the beams (and surface photons) of this iteration's light paths, traced first,
    // with the iteration's radii; camera paths started.
    void begin(int64_t iteration);
    double radius(int64_t iteration, int medium = 0) const { return beam_schedule(medium).radius(iteration); }
    const RadiusSchedule &beam_schedule(int medium) const;
    // The radius schedule of each blur: the beams' (1D; one alpha for every medium), then the
    // surface photons' (2D) if any.
    std::vector<RadiusSchedule> schedules() const {
        if (surface_photons_) return {schedules_[0], surface_schedule_};
        return {schedules_[0]};
    }
    double surface_radius(int64_t iteration) const {
        return surface_photons_ ? surface_schedule_.radius(iteration) : 0.0;
    }
    // Pass 2 (with next_rays and the shadow passes, repeated): gather beams along each traced
    // segment, then the surface (emission, NEE, photons or BSDF sampling). Returns the number
    // of queued shadow rays.
    size_t next_rays(const RayBuffers &out);
    size_t shade(const Hits &hits);
    size_t shadow_rays(const RayBuffers &out) { return shadow_.compact_and_write(out, threads_); }
    void resolve_shadows(const Hits &hits);
    // Pass 3: path radiance to the film, in path order.
    void end();

    const Film &film() const { return film_; }
    const Scene &scene() const { return *scene_; }
    const BeamBvh &bvh() const { return bvh_; }
    const BeamStats &stats() const { return stats_; }
    uint64_t density_lookups() const { return stats_.density_lookups; }

private:
    RGB gather(BeamGatherPath &p, double t_end, const BoundaryPlane &exit, MediumStats &local, uint64_t &pairs) const;
    double pilot_beams(const BeamGatherPath &p, double t_end, Sampler rng, double &free_path) const;
    double pilot_photons(const BeamGatherPath &p, int tri, const Vec3 &x) const;
    void scatter_on_surface(BeamGatherPath &p, size_t slot, int tri, const Vec3 &x);
    RGB gather_photons(const BeamGatherPath &p, int tri, const Vec3 &x) const;

    std::shared_ptr<const Scene> scene_;
    std::shared_ptr<const LightPaths> light_paths_;
    CameraPathSteps steps_;
    DepthLimit depth_;
    uint64_t seed_;
    int spp_per_iteration_, threads_;
    double max_piece_length_;
    int gather_diffuse_bounces_;
    std::vector<BeamGatherPath> paths_;
    std::vector<int32_t> active_;
    ShadowQueue shadow_;
    Film film_;
    BeamBvh bvh_;
    std::vector<RadiusSchedule> schedules_;  // of the beams, by medium
    bool surface_photons_ = false;
    RadiusSchedule surface_schedule_;
    std::vector<PathVertex> photons_;  // surface vertices after at least one scattering
    PointTree photon_tree_;
    double photon_radius_ = 0, photon_scale_ = 0;  // r and 1 / (pi r^2 N_light_paths)
    std::vector<double> beam_radii_, beam_scales_;  // this iteration's r and 1 / (2 r N_light_paths), by medium
    RadiusPilot pilot_{"ppb"};
    BeamStats stats_;
    MediumStats medium_stats_;
};

}  // namespace pgi
