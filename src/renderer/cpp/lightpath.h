// Light paths shared by the light-side methods (lt, pm, sppm, ppb, and the bidirectional and
// virtual-light methods to come): a kernel that traces N light paths per iteration and records
// their scattering vertices and their straight segments inside media (path_records.h).
//   Veach 1997, "Robust Monte Carlo methods for light transport simulation",
//     ch. 5 (adjoint BSDFs) and ch. 10 (particle tracing);
//   Jensen 2001, "Realistic Image Synthesis Using Photon Mapping" (emission, photon power).
//
// API (stable; other methods build on it)
// ---------------------------------------
//   LightPaths(scene, max_depth, rr_depth, seed, paths_per_iteration, threads, max_records)
//       paths start in the medium the scene says each light emits into
//       (Scene::set_emission_media)
//   set_recording(vertices, segments, complete)  what to record (default: vertices where a
//       camera path can connect or gather, and segments); `complete` records every vertex,
//       the lights' own and delta ones included, with their densities (path_records.h)
//   One iteration is the protocol of passes.h, run by renderer/wavefront.py:
//     begin(i)          emission sampling for every path
//     next_rays(rays)   extension rays of the paths still alive
//     shade(hits)       medium free flight, surface or medium scattering, recording of vertices
//                       and segments, Russian roulette
//   Then read vertices() and segments(): records of this iteration only, in a fixed order
//   (bounce by bounce, path index ascending within a bounce) whatever the thread count.
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
#pragma once

#include <memory>
#include <vector>

#include "passes.h"
#include "path_records.h"

namespace pgi {

// What a vertex of a complete subpath keeps for the densities of its neighbours
// (path_records.h): the density of the next vertex needs how the direction on was sampled,
// and the reverse density of the vertex before needs the direction back and that vertex. Every
// direction and cosine is taken from the recorded positions (the rays leaving surfaces start
// offset off them), so that densities are functions of the recorded path.
struct DensityVertex {
    enum class Sampling : uint8_t { Stored, Cosine, Phase, Dielectric };
    Vec3 pos;
    Vec3 normal;              // its surface's normal (zero in a medium, at point and
                              // directional lights)
    Vec3 wi;                  // unit, towards the vertex before it (zero at a light)
    double pdf_dir = 0;       // Stored: the density of the direction sampled there (a mirror's
                              // 1, a point or spot light's, a directional light's disk's area
                              // density); Dielectric: the interface's ior (the discrete
                              // probability of reflection or refraction follows the directions)
    double sigma = 0;         // its extinction, if it lies in a medium
    double tau_in = 0;        // stand-in optical depth of the edge from the vertex before
    int64_t record = -1;      // its index in the vertices of this iteration (-1: none yet)
    int32_t medium = -1;      // Phase: the medium whose phase function sampled
    Sampling sampling = Sampling::Stored;  // Cosine: about `normal` (diffuse, area lights)
    bool at_infinity = false; // a directional light's: parallel rays, no 1 / distance^2
    bool delta_light = false; // a light's delta position or direction: never sampled back
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

class LightPaths : public SingleLane<LightPaths>, public NoShadowRays {
public:
    LightPaths(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed,
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
    // complete subpaths with their densities (path_records.h).
    void set_recording(bool vertices, bool segments, bool complete = false) {
        record_vertices_ = vertices || complete;
        record_segments_ = segments;
        complete_ = complete;
    }
    bool complete() const { return complete_; }

private:
    void emit(LightPathState &p, size_t slot);
    void scatter_in_medium(LightPathState &p, size_t slot, const Vec3 &x, MediumStats &stats);
    void scatter_on_surface(LightPathState &p, size_t slot, int tri, const Vec3 &x);
    bool russian_roulette(LightPathState &p);
    PathVertex &record_vertex(size_t slot, const LightPathState &p, VertexKind kind, const Vec3 &x, const Vec3 &wi);
    // Complete subpaths: the densities once a new vertex is known (its forward one, and the
    // reverse one of the vertex two back), and its entry among the path's last two vertices.
    DensityTrack &track(const LightPathState &p) { return tracks_[size_t(&p - paths_.data())]; }
    double forward_density(const DensityTrack &t, const DensityVertex &x) const;
    void reverse_density(const DensityTrack &t, const DensityVertex &x);
    void advance_densities(LightPathState &p, DensityVertex x, PathVertex *record);
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
    std::vector<LightPathState> paths_;
    std::vector<DensityTrack> tracks_;  // complete subpaths: one per path
    std::vector<int32_t> active_;
    // One optional vertex and segment per active path and pass.
    std::vector<PathVertex> slot_vertex_;
    std::vector<MediumSegment> slot_segment_;
    std::vector<uint8_t> slot_has_vertex_, slot_has_segment_;
    std::vector<PathVertex> vertices_;
    std::vector<MediumSegment> segments_;
    bool record_vertices_ = true, record_segments_ = true, complete_ = false;
    MediumStats stats_;
    uint64_t paths_traced_ = 0;
};

}  // namespace pgi
