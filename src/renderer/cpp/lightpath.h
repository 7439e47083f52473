// Light-path tracing shared by the light-side methods (lt, pm, sppm, ppb):
// a wavefront tracer of N light paths per iteration that records every
// scattering vertex and every straight segment inside a medium.
//   Veach 1997, "Robust Monte Carlo methods for light transport simulation",
//     ch. 5 (adjoint BSDFs) and ch. 10 (particle tracing);
//   Jensen 2001, "Realistic Image Synthesis Using Photon Mapping" (emission, photon power).
//
// API (stable; other methods build on it)
// ---------------------------------------
//   LightPathTracer(scene, max_depth, rr_depth, seed, paths_per_iteration, threads, max_records)
//   set_emission_media(per_triangle, per_light)  medium each light emits into (-1 = vacuum);
//                                                the Python side finds them by probing rays
//                                                (renderer/methods/lightpath.py)
//   One iteration, driven from Python (renderer/methods/lightpath.py: LightPaths.trace):
//     n = begin_iteration(i, rays)   pass 1: emission sampling for every path; writes n rays
//     while n:
//       scatter(hits)                pass 2: medium free flight, surface/medium scattering,
//                                    recording of vertices and segments, Russian roulette
//       n = next_rays(rays)          pass 3: extension rays of the paths still alive
//   Then read vertices() and segments(): records of this iteration only, in a fixed order
//   (bounce by bounce, path index ascending within a bounce) whatever the thread count.
//
// Units: `power` is a flux weight. For any function g of a vertex,
//   E[ sum over the iteration's vertices of power * g(vertex) ] / paths_per_iteration
// is the integral of g against the flux arriving at such vertices (Veach 1997,
// sec. 10.2, particle tracing as a measurement): divide sums by
// paths_per_iteration(), never by the number of records.
//   - Emission vertices (area lights only; point, spot and directional
//     emitters cannot be seen by a pinhole camera): power = Le / pdf_A (pdf_A
//     includes the light selection). The emitted radiance towards a direction w
//     is then power * max(0, cos(n, w)); `wi` holds the light's normal n.
//   - Surface vertices (non-delta surfaces, light arriving on the front side):
//     power = flux arriving. Outgoing flux towards w is power * f(wi, w) * |cos(n, w)|
//     with the adjoint BSDF (diffuse: reflectance / pi).
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
#pragma once

#include <memory>
#include <vector>

#include "passes.h"

namespace pgi {

enum class VertexKind : uint8_t { Emission = 0, Surface = 1, Medium = 2 };

struct LightVertex {
    Vec3 pos;
    Vec3 wi;                 // unit, from pos back towards the previous vertex (emission: light normal)
    RGB power{0.0};          // flux weight, see above
    int32_t path = 0;        // index of the path within its iteration
    int32_t triangle = -1;   // surface and emission vertices
    int32_t medium = -1;     // medium vertices: the medium; surface: the medium on the side of wi
    int16_t depth = 0;       // real scattering events up to and including this vertex
    VertexKind kind = VertexKind::Surface;
    bool after_specular = false;  // the previous real event was a delta BSDF (caustic light)
};

// Depths are stored in 16 bits: the loader keeps min(rr_depth, bounded max_depth) <= 10000
// and roulette lets a path on with probability at most 0.95 after rr_depth, so a path of
// 32767 events has a probability under 0.95^22767, about 1e-507.
struct LightSegment {
    Vec3 origin, dir;        // dir unit
    double length = 0;       // to the sampled collision, or t_surface when none was sampled
    double t_surface = 0;    // to the next surface along dir (kInf when the ray escapes)
    RGB power{0.0};          // flux weight at the origin, before this segment's transmittance
    RGB spectral_ratio{1.0}; // the path's channel pdf ratios at the origin (SpectralMis)
    int32_t path = 0;
    int32_t medium = -1;
    int16_t depth = 0;       // real scattering events before the origin
    bool scattered = false;  // a medium vertex (if in range) follows at origin + dir * length
};

struct LightPathState {
    Vec3 pos, dir;
    double lead = 0;  // medium behind pos (start_path_at)
    RGB power{0.0};
    double inv_initial = 1;  // 1 / max component of the emitted power (Russian roulette)
    int medium = -1;
    int depth = 0;
    int null_crossings = 0;
    bool after_specular = false;
    bool alive = false;
    Sampler rng;
    SpectralMis spectral;  // hero channel and path pdf ratios in chromatic media
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
    bool has_direction = false;
};
EmissionSample sample_emission(const Scene &scene, const double u[6]);

class LightPaths : public SingleLane<LightPaths>, public NoShadowRays {
public:
    LightPaths(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed,
               int64_t paths_per_iteration, int threads, int64_t max_records);

    // Medium at each emitting triangle's front side and at each point/spot light.
    void set_emission_media(const std::vector<int32_t> &per_triangle, const std::vector<int32_t> &per_light);

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

    const std::vector<LightVertex> &vertices() const { return vertices_; }
    const std::vector<LightSegment> &segments() const { return segments_; }
    int64_t iteration() const { return iteration_; }
    uint64_t density_lookups() const { return stats_.density_lookups; }
    uint64_t paths_traced() const { return paths_traced_; }

    // Record only what a method needs (defaults: everything).
    void set_recording(bool vertices, bool segments) {
        record_vertices_ = vertices;
        record_segments_ = segments;
    }

private:
    void emit(LightPathState &p, size_t slot);
    void scatter_in_medium(LightPathState &p, size_t slot, const Vec3 &x);
    void scatter_on_surface(LightPathState &p, size_t slot, int tri, const Vec3 &x);
    bool russian_roulette(LightPathState &p);
    LightVertex &record_vertex(size_t slot, const LightPathState &p, VertexKind kind, const Vec3 &x, const Vec3 &wi);
    void collect(size_t slots);  // appends per-slot records in slot order
    void check_capacity() const;

    std::shared_ptr<const Scene> scene_;
    DepthLimit depth_;
    int rr_depth_;
    uint64_t seed_;
    int threads_;
    int64_t max_records_;
    int64_t iteration_ = -1;
    std::vector<LightPathState> paths_;
    std::vector<int32_t> active_;
    std::vector<int32_t> emission_medium_triangle_, emission_medium_light_;
    // One optional vertex and segment per active path and pass.
    std::vector<LightVertex> slot_vertex_;
    std::vector<LightSegment> slot_segment_;
    std::vector<uint8_t> slot_has_vertex_, slot_has_segment_;
    std::vector<LightVertex> vertices_;
    std::vector<LightSegment> segments_;
    bool record_vertices_ = true, record_segments_ = true;
    MediumStats stats_;
    uint64_t paths_traced_ = 0;
};

}  // namespace pgi
