// Subpaths: the kernels that trace N paths per iteration from the lights (LightPaths: lt, pm,
// sppm, ppb, bdpt and the virtual-light methods) or from the camera (CameraPaths: bdpt), and
// record their scattering vertices and their straight segments inside media (path_records.h).
//   Veach 1997, "Robust Monte Carlo methods for light transport simulation",
//     ch. 5 (adjoint BSDFs) and ch. 10 (particle tracing, bidirectional path tracing);
//   Jensen 2001, "Realistic Image Synthesis Using Photon Mapping" (emission, photon power).
//
// API (stable; other methods build on it)
// ---------------------------------------
//   LightPaths(scene, max_depth, rr_depth, seed, paths_per_iteration, threads, max_records)
//   CameraPaths(scene, max_depth, rr_depth, seed, spp_per_iteration, threads, max_records):
//       paths_per_iteration = spp_per_iteration camera samples per pixel (path i: pixel
//       i % pixels, as camera_path.h's start_camera_sample)
//   set_recording(vertices, segments, complete)  what to record (default: vertices where a
//       camera path can connect or gather, and segments); `complete` records every vertex,
//       the lights' own and the camera's, delta ones included, with their densities
//       (path_records.h, densities.h). Camera paths always record complete subpaths.
//   Each light emits into the medium the scene decided for it (Scene::set_emission_media).
//   One iteration is the protocol of passes.h, run by renderer/wavefront.py:
//     begin(i)          emission (or a camera sample) for every path
//     next_rays(rays)   extension rays of the paths still alive
//     shade(hits)       medium free flight, surface or medium scattering, recording of vertices
//                       and segments, Russian roulette
//   Then read vertices() and segments(): records of this iteration only, in a fixed order
//   (bounce by bounce, path index ascending within a bounce, so each path's vertices come in
//   the order of their depth) whatever the thread count.
//
// Units: a light vertex's `throughput` is its power, a flux weight. For any function g of a
// vertex,
//   E[ sum over the iteration's vertices of power * g(vertex) ] / paths_per_iteration
// is the integral of g against the flux arriving at such vertices (Veach 1997,
// sec. 10.2, particle tracing as a measurement): divide sums by
// paths_per_iteration(), never by the number of records.
//   - Emission vertices: power = Le / pdf_A (pdf_A includes the light selection). The emitted
//     radiance towards a direction w is then power * max(0, cos(n, w)); `wi` holds the light's
//     normal n. By default only area lights have one (point, spot and directional emitters
//     cannot be seen by a pinhole camera); complete subpaths start with the light's vertex
//     whatever its type (power = the emitted flux weight before the direction is sampled:
//     intensity / pick, and irradiance / (pdf_disk pick) for a directional light).
//   - Surface vertices (non-delta surfaces, light arriving on the front side; complete
//     subpaths also keep delta surfaces): power = flux arriving. Outgoing flux towards w is
//     power * f(wi, w) * |cos(n, w)| with the adjoint BSDF (diffuse: reflectance / pi).
//   - Medium vertices (real collisions): power already includes sigma_s (the
//     free-flight weight sigma_s Tr / pdf), so in-scattered radiance towards w is
//     power * phase(wi, w) per unit volume density of vertices.
//   - Segments: power at the origin, *before* the transmittance of the segment.
//     With the free-flight sampling of medium.h the collision density along a
//     segment is pdf(t) = sigma_t Tr(t) (grid: delta tracking, gray) or
//     mean_c(sigma_t,c Tr_c(t)) (homogeneous, hero channel): a "short beam" of
//     flux at distance s < length is power * Tr(s) / P(t > s), with
//     P(t > s) = mean_c(spectral_ratio_c Tr_c(s)) (homogeneous: the path's hero channel
//     samples every flight, medium.h SpectralMis; the ratio is the segment's) or Tr(s)
//     (grid); a "long beam" up to
//     t_surface uses power * Tr(s) and must ignore the sampled collision.
// Depth (Mitsuba's max_depth): a vertex's `depth` counts the real scattering
// events of the light path up to and including it (emission: 0, first hit: 1).
// A path camera <- vertex built by connecting or gathering, with s further
// scattering events on the camera side, is in range iff DepthLimit::allows(depth + s)
// (common.h). Records out of range for s = 0 are not made.
// A segment's `depth` counts the events before its origin: a scattering point on
// it makes a vertex of depth + 1. Null boundaries and null collisions are free.
// Adjoint transport: refraction is sampled with `radiance = false` (no 1/eta^2
// scaling of importance). Normals are flat, so no shading-normal correction.
// Camera paths carry radiance: refraction scales their throughput by 1/eta^2 and roulette
// takes eta^2 back (as pt's); a camera vertex's throughput is the path's weight for its pixel
// sample (1 at the camera: a box-filtered pinhole samples each pixel as its importance does).
#pragma once

#include <memory>
#include <vector>

#include "camera_path.h"
#include "densities.h"
#include "passes.h"
#include "path_records.h"

namespace pgi {

// Which end of the scene a kernel's paths start from.
enum class Side : uint8_t { Light, Camera };

struct SubpathState {
    Vec3 pos, dir;
    double lead = 0;  // medium behind pos (start_path_at)
    RGB power{0.0};   // the path's weight: a light path's flux, a camera path's throughput
    double inv_initial = 1;  // Russian roulette: 1 / max component of the emitted power
    double eta2 = 1;         // camera paths: product of squared IOR ratios crossed (roulette)
    int64_t pixel = 0;       // camera paths: the pixel sampled
    int medium = -1;
    int depth = 0;
    int null_crossings = 0;
    bool after_specular = false;
    bool alive = false;
    Sampler rng;
    SpectralMis spectral;  // hero channel and path pdf ratios in chromatic media
};

// What a complete subpath keeps for its densities (kept beside its state, only when complete
// subpaths are recorded): its last two vertices, the stand-in optical depth travelled since
// the last (summed over the pieces of the straight line from it between the null boundaries
// crossed, not over the rays, whose origins are offset) and where the current piece starts.
struct DensityTrack {
    DensityVertex last, before;
    double flight_tau = 0;
    Vec3 piece_start;
};

// What emission samples from six uniforms (u[0] picks the light, u[1] an area light's
// triangle, u[2..3] the point on it, u[4..5] the direction): the light, where the path
// starts (an area light's point, a point or spot light's position, a point on a directional
// light's disk before the scene), its direction and starting power. Area lights also give the
// emission vertex's power Le A / pick; has_direction is false where no direction was drawn.
struct EmissionSample {
    int light = -1;
    int triangle = -1;
    Vec3 pos, dir;
    RGB power{0.0}, vertex_power{0.0};
    double pdf_pos = 0;  // area density of pos (selection included; delta positions: the pick)
    double pdf_dir = 0;  // density of dir: solid angle; a directional light's disk: area
    bool has_direction = false;
};
EmissionSample sample_emission(const Scene &scene, const double u[6]);

template <Side S>
class Subpaths : public SingleLane<Subpaths<S>>, public NoShadowRays {
public:
    // paths_per_iteration: light paths; for camera paths, samples per pixel (times the pixels).
    Subpaths(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed,
             int64_t paths_per_iteration, int threads, int64_t max_records);

    size_t capacity() const { return paths_.size(); }
    int64_t paths_per_iteration() const { return int64_t(paths_.size()); }
    int max_depth() const { return depth_.max_depth(); }
    int threads() const { return threads_; }
    const Scene &scene() const { return *scene_; }
    std::shared_ptr<const Scene> scene_ptr() const { return scene_; }

    // The passes (passes.h): begin emits every path, shade scatters them where their rays
    // ended (recording vertices and segments), end has nothing left to do.
    void begin(int64_t iteration);
    size_t next_rays(const RayBuffers &out);
    size_t shade(const Hits &hits);
    void end() {}

    const std::vector<PathVertex> &vertices() const { return vertices_; }
    const std::vector<MediumSegment> &segments() const { return segments_; }
    int64_t iteration() const { return iteration_; }
    uint64_t density_lookups() const { return stats_.density_lookups; }
    uint64_t paths_traced() const { return paths_traced_; }

    // Record only what a method needs (defaults: connectible vertices and segments), or
    // complete subpaths with their densities (path_records.h). Camera paths are always
    // complete (there is nothing else to record of them).
    void set_recording(bool vertices, bool segments, bool complete = false) {
        record_vertices_ = vertices || complete || S == Side::Camera;
        record_segments_ = segments;
        complete_ = complete || S == Side::Camera;
    }
    bool complete() const { return complete_; }

private:
    void emit(SubpathState &p, size_t slot);
    void start_at_camera(SubpathState &p, size_t slot, int64_t iteration);
    void scatter_in_medium(SubpathState &p, size_t slot, const Vec3 &x, MediumStats &stats);
    void scatter_on_surface(SubpathState &p, size_t slot, int tri, const Vec3 &x);
    bool russian_roulette(SubpathState &p);
    PathVertex &record_vertex(size_t slot, const SubpathState &p, VertexKind kind, const Vec3 &x, const Vec3 &wi);
    // Complete subpaths: the densities once a new vertex is known (its forward one, and the
    // reverse one of the vertex two back), and its entry among the path's last two vertices.
    DensityTrack &track(const SubpathState &p) { return tracks_[size_t(&p - paths_.data())]; }
    double forward_density(const DensityTrack &t, const DensityVertex &x) const;
    void reverse_density(const DensityTrack &t, const DensityVertex &x);
    void advance_densities(SubpathState &p, DensityVertex x, PathVertex *record);
    // Appends the per-slot records in slot order; `path_of(slot)` is the slot's path.
    template <typename PathOf>
    void collect(size_t slots, PathOf &&path_of);
    void check_capacity() const;

    std::shared_ptr<const Scene> scene_;
    DepthLimit depth_;
    int rr_depth_;
    uint64_t seed_;
    int threads_;
    int64_t max_records_;
    int64_t iteration_ = -1;
    std::vector<SubpathState> paths_;
    std::vector<DensityTrack> tracks_;  // complete subpaths: one per path
    std::vector<int32_t> active_;
    // One optional vertex and segment per active path and pass.
    std::vector<PathVertex> slot_vertex_;
    std::vector<MediumSegment> slot_segment_;
    std::vector<uint8_t> slot_has_vertex_, slot_has_segment_;
    std::vector<PathVertex> vertices_;
    std::vector<MediumSegment> segments_;
    bool record_vertices_ = true, record_segments_ = true, complete_ = S == Side::Camera;
    int camera_spp_ = 1;  // camera paths: samples per pixel per iteration
    MediumStats stats_;
    uint64_t paths_traced_ = 0;
};

using LightPaths = Subpaths<Side::Light>;
using CameraPaths = Subpaths<Side::Camera>;

}  // namespace pgi
