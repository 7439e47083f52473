// Virtual lights: the light that light paths leave at their vertices, kept as light sources of
// their own and gathered where camera paths meet the scene (Keller 1997, "Instant radiosity").
// Shared by the methods that gather them: vpl and vsl (a vertex as a point or spread over a
// sphere), and the pieces a gather of ray lights (vrl, vbl: a light path's medium segments) needs
// too: the camera paths that find where to gather, the records of those places (gather jobs),
// the transmittance along a camera segment, and the stream of shadow rays that joins every job to
// every light.
//
// Virtual lights (VirtualLight). Each iteration's light paths (subpaths.h, default recording)
// give one per recorded vertex: an area light's own point (AreaLight), a non-delta surface
// vertex lit from the front (Surface) and a real collision in a medium (Medium); point, spot and
// directional lights give one each, exact: the expectation of their light paths' own vertices
// (each of the N paths picks light l with probability P_l and records power I / P_l, so
// E[sum / N] = I), which is their direct light with no sampling noise. `power` is the flux weight
// a light carries in this iteration's estimate, the division by N already made:
//   surface:   L(x -> w_o) = sum_y power_y F_x(w_o, w) F_y(-w) G(x, y) V T(x, y)
//   medium:    the same at a point of a camera segment, times sigma_s there
// with w the unit direction from x to y, G = 1 / |x - y|^2 (no cosines: they are in F) and
//   F_x: the BSDF times |cos| at a surface point (bsdf_eval), the phase function in a medium;
//   F_y: the light leaving y towards -w per unit power: the adjoint BSDF times |cos| (Surface),
//        the phase function (Medium; sigma_s is in its power), |cos| about the light's normal
//        (AreaLight, power Le / pdf_A), 1 (Point), the spot's falloff (Spot), and for a
//        directional light its irradiance along its one direction, with no G.
//
// Gather jobs (GatherJob): a camera path's place to gather, a surface point or a straight medium
// segment, with the path's throughput there and its count of real camera-side events (a path
// made by joining light y of depth k to a job of s events has k + s events: DepthLimit::allows).
// The camera paths that find them (GatherCameraPath, GatherWalk) follow specular chains from the
// camera and gather at the first non-specular vertex; the walk and the coverage it gives are
// explained at GatherWalk.
//
// The connection stream (ConnectionStream) joins every job to every light through shadow rays,
// in chunks of a fixed number of pairs, so that memory stays bounded whatever jobs x lights is,
// and adds each chunk's values to their jobs in pair order (the image does not depend on the
// thread count).
#pragma once

#include <utility>
#include <vector>

#include "camera_path.h"
#include "subpaths.h"

namespace pgi {

enum class VirtualLightKind : uint8_t { Surface, Medium, AreaLight, Point, Spot, Directional };

struct VirtualLight {
    Vec3 pos;        // unused for a directional light
    Vec3 axis;       // Surface, Medium: wi (unit, towards the light path's previous vertex);
                     // AreaLight: the light's normal; Spot: its axis; Directional: its direction
                     // of travel
    RGB power{0.0};  // flux weight in this iteration's estimate (divided by the light paths)
    int32_t triangle = -1;  // Surface, AreaLight
    int32_t medium = -1;    // Medium: its medium; lights: the medium they emit into
    int32_t light = -1;     // lights: the core's light index
    int16_t depth = 0;      // real scattering events of the light path up to y (lights: 0)
    VirtualLightKind kind = VirtualLightKind::Surface;
    // A light's own delta position or direction: gathered exactly as it is, never clamped or
    // spread (its 1 / d^2 is the light's own, not a sampling artefact).
    bool exact() const { return kind >= VirtualLightKind::Point; }
};

// This iteration's virtual lights: the exact lights first (by light index), then one per
// recorded light-path vertex, in record order (deterministic).
inline std::vector<VirtualLight> collect_virtual_lights(const Scene &scene, const LightPaths &paths) {
    std::vector<VirtualLight> out;
    const double inv_paths = 1.0 / double(paths.paths_per_iteration());
    for (size_t i = 0; i < scene.lights.size(); ++i) {
        const Light &l = scene.lights[i];
        if (l.type == LightType::Area) continue;
        VirtualLight v;
        v.kind = l.type == LightType::Point  ? VirtualLightKind::Point
                 : l.type == LightType::Spot ? VirtualLightKind::Spot
                                             : VirtualLightKind::Directional;
        v.pos = l.position;
        v.axis = l.direction;
        v.power = l.intensity;
        v.light = int32_t(i);
        v.medium = scene.light_emission_medium(int(i));
        if (!is_black(v.power)) out.push_back(v);
    }
    for (const PathVertex &p : paths.vertices()) {
        VirtualLight v;
        v.pos = p.pos;
        v.axis = p.wi;
        v.power = p.throughput * inv_paths;
        v.triangle = p.triangle;
        v.medium = p.medium;
        v.light = p.light;
        v.depth = p.depth;
        if (p.kind == VertexKind::Emission) {
            if (p.triangle < 0) continue;  // a delta light's vertex (complete recording): exact above
            v.kind = VirtualLightKind::AreaLight;
        } else if (p.kind == VertexKind::Medium) {
            v.kind = VirtualLightKind::Medium;
        } else if (p.kind == VertexKind::Surface) {
            if (scene.materials[scene.triangles[p.triangle].material].is_delta()) continue;
            v.kind = VirtualLightKind::Surface;
        } else {
            continue;
        }
        if (!is_black(v.power)) out.push_back(v);
    }
    return out;
}

// F_y: the light leaving virtual light y towards `out` (unit), per unit of its power (above).
inline RGB virtual_light_emission(const Scene &scene, const VirtualLight &y, const Vec3 &out) {
    switch (y.kind) {
        case VirtualLightKind::Surface: {
            const Triangle &T = scene.triangles[size_t(y.triangle)];
            return bsdf_eval(scene.materials[size_t(T.material)], T.n, y.axis, out);
        }
        case VirtualLightKind::Medium: return RGB(phase_eval(scene.media[size_t(y.medium)].phase, y.axis, out));
        case VirtualLightKind::AreaLight: return RGB(std::max(0.0, dot(y.axis, out)));
        case VirtualLightKind::Spot: return RGB(scene.lights[size_t(y.light)].spot_falloff(out));
        default: return RGB(1.0);
    }
}

// The lobe of a spread light (Surface, Medium, AreaLight) as a distribution of directions
// leaving it: cosine-weighted about a surface's or a light's front normal, the phase function in
// a medium; its density per solid angle.
inline Vec3 sample_virtual_light_lobe(const Scene &scene, const VirtualLight &y, double u1, double u2, double &pdf) {
    if (y.kind == VirtualLightKind::Medium) return phase_sample(scene.media[size_t(y.medium)].phase, y.axis, u1, u2, pdf);
    const Vec3 n = y.kind == VirtualLightKind::AreaLight ? y.axis : scene.triangles[size_t(y.triangle)].n;
    const Vec3 local = square_to_cosine_hemisphere(u1, u2);
    pdf = local.z * kInvPi;
    return Frame(n).to_world(local);
}
inline double virtual_light_lobe_pdf(const Scene &scene, const VirtualLight &y, const Vec3 &out) {
    if (y.kind == VirtualLightKind::Medium) return phase_eval(scene.media[size_t(y.medium)].phase, y.axis, out);
    const Vec3 n = y.kind == VirtualLightKind::AreaLight ? y.axis : scene.triangles[size_t(y.triangle)].n;
    return std::max(0.0, dot(n, out)) * kInvPi;
}

// Where a camera path gathers: a point x on a non-delta surface (triangle) or in a medium, seen
// from wo (unit, towards the camera side). `medium`: the medium x lies in, or for a surface point
// the medium on wo's side.
struct GatherPoint {
    Vec3 pos, wo;
    int32_t triangle = -1;
    int32_t medium = -1;
    bool on_surface() const { return triangle >= 0; }
};

// F_x: the BSDF times |cos| at a surface point, the phase function at a medium point.
inline RGB gather_scattering(const Scene &scene, const GatherPoint &x, const Vec3 &out) {
    if (!x.on_surface()) return RGB(phase_eval(scene.media[size_t(x.medium)].phase, x.wo, out));
    const Triangle &T = scene.triangles[size_t(x.triangle)];
    return bsdf_eval(scene.materials[size_t(T.material)], T.n, x.wo, out);
}
// Sampling F_x's lobe: cosine-weighted about the normal (a diffuse surface seen from its front),
// the phase function in a medium; the density per solid angle.
inline Vec3 sample_gather_direction(const Scene &scene, const GatherPoint &x, double u1, double u2, double &pdf) {
    if (!x.on_surface()) return phase_sample(scene.media[size_t(x.medium)].phase, x.wo, u1, u2, pdf);
    const Vec3 local = square_to_cosine_hemisphere(u1, u2);
    pdf = local.z * kInvPi;
    return Frame(scene.triangles[size_t(x.triangle)].n).to_world(local);
}
inline double gather_direction_pdf(const Scene &scene, const GatherPoint &x, const Vec3 &out) {
    if (!x.on_surface()) return phase_eval(scene.media[size_t(x.medium)].phase, x.wo, out);
    return std::max(0.0, dot(scene.triangles[size_t(x.triangle)].n, out)) * kInvPi;
}

// Aims shadow ray r from gather point x at virtual light y, along `dir` (unit, x -> y; for a
// directional light, against its direction of travel): it starts an offset off x's surface (or
// at x in a medium) and stops short of a light or a surface (an offset), nowhere short of a point
// in a medium. The caller sets contribution, receiver, rng and live.
inline void aim_at_virtual_light(const Scene &scene, ShadowRay &r, const GatherPoint &x, const VirtualLight &y,
                                 const Vec3 &dir) {
    r.dir = dir;
    r.to_infinity = y.kind == VirtualLightKind::Directional;
    r.target = r.to_infinity ? Vec3() : y.pos;
    switch (y.kind) {
        case VirtualLightKind::Point:
        case VirtualLightKind::Spot: r.target_eps = scene.light_clearance(y.pos); break;
        case VirtualLightKind::Surface:
        case VirtualLightKind::AreaLight: r.target_eps = scene.offset_length(y.pos); break;
        default: r.target_eps = 0;
    }
    if (x.on_surface()) {
        r.medium = scene.triangles[size_t(x.triangle)].medium_after(x.medium, dir);
        r.restart_at(scene.spawn(x.pos, x.triangle, dir));
    } else {
        r.medium = x.medium;
        r.restart_at(RayStart{x.pos});
    }
    r.tau = 0;
}

// Transmittance from the start of a camera segment to many distances along it: closed form in
// homogeneous media; in density grids one ratio-tracking walk, whose running product up to t
// estimates Tr(0, t) without bias for every t at once (medium.h, ratio_track).
class TransmittanceTrack {
public:
    TransmittanceTrack() = default;
    TransmittanceTrack(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Sampler &rng, MediumStats &stats)
        : medium_(&m) {
        if (m.type == MediumType::Homogeneous) return;
        ++stats.segments;
        ratio_track(m, o, d, tmax, rng, stats, [&](double t, double tr) { steps_.push_back({t, tr}); });
    }
    RGB at(double t) const {
        if (medium_->type == MediumType::Homogeneous) return beer_lambert(medium_->sigma_t, t);
        size_t lo = 0, hi = steps_.size();  // the last step before t
        while (lo < hi) {
            const size_t mid = (lo + hi) / 2;
            if (steps_[mid].first < t) lo = mid + 1; else hi = mid;
        }
        return RGB(lo == 0 ? 1.0 : steps_[lo - 1].second);
    }

private:
    const Medium *medium_ = nullptr;
    std::vector<std::pair<double, double>> steps_;
};

// The extinction of medium m at x times its albedo: sigma_s(x).
inline RGB scattering_coefficient(const Medium &m, const Vec3 &x, MediumStats &stats) {
    if (m.type == MediumType::Homogeneous) return m.sigma_t * m.albedo;
    return m.albedo * grid_sigma_t(m, x, stats);
}

// Where a ray (o, d) over [0, tmax) runs inside a density grid's box, [*lo, *hi) (empty: false).
inline bool grid_span(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, double &lo, double &hi) {
    lo = kInf;
    hi = -kInf;
    traverse_majorants(m, o, d, tmax, [&](double t0, double t1, double) {
        lo = std::min(lo, t0);
        hi = std::max(hi, t1);
        return true;
    });
    return hi > lo;
}

// A place where a camera path gathers (see the top of this file).
struct GatherJob {
    GatherPoint at;      // a surface point; for a medium segment, its origin and medium (wo = -d)
    double length = 0;   // medium segment: [0, length) from at.pos along -at.wo (may be infinite)
    RGB weight{0.0};     // the camera path's throughput at the point, or at the segment's origin
    int64_t path = 0;    // the camera path (its slot in the wave: pixel path % pixels, sample
                         // path / pixels of the iteration's)
    int32_t track = -1;  // medium segment in a grid: its TransmittanceTrack
    int16_t events = 0;  // camera-side real events of a path through it, the gather vertex's included
    Sampler rng;         // the job's stream: light j takes the child split(j)
    bool segment() const { return !at.on_surface(); }
    Vec3 dir() const { return -at.wo; }
};

// Camera paths of a gathering method (GatherWalk).
struct GatherCameraPath : CameraPath {
    bool gathering = true;  // the path's last real vertex is the camera or a specular one
};

// The walk of the camera paths of a gathering method, one traced ray at a time.
//
// A path starts at the camera gathering. While gathering, it follows null boundaries and
// specular (delta) surfaces; every medium segment it crosses is a segment job (the lights are
// gathered along it), emission it reaches is added with full weight (nothing else samples a path
// camera -> specular chain -> light), and the first non-delta surface is a surface job. Every
// light path vertex y that a straight, unscattered line joins to a gather point x then makes
// the path camera -> ... -> x -> y -> ... -> light. What no such join can make is a path whose
// vertex after x is specular (x -> glass -> ...): for those the path goes on from x
// (`continuations`, in scenes with a specular surface), sampling a direction by the BSDF at a
// surface job or, in a medium, a free-flight collision and the phase function, and no longer
// gathering: a continuing path carries the transmittance of the media it crosses and ends at the
// first non-delta surface or medium collision (the lights gathered at x made those paths
// already), adds no emission (x's light vertices did), and gathers again after its next specular
// bounce. So every path from the camera is made once: by the gather at the last non-specular
// camera-side vertex whose next vertex is not specular, or by emission at the end of a
// specular chain. Where a gathering segment in such a scene may end in a collision, the path's
// free flight decides between the surface (weight Tr / P(pass)) and a continuation from the
// collision; in scenes without specular surfaces no path continues, and the surface job takes the
// segment's transmittance in closed form (homogeneous media) or from the scene's estimator.
// Russian roulette as pt's (CameraPathSteps) after rr_depth real events; Mitsuba's max_depth.
class GatherWalk {
public:
    GatherWalk(const Scene &scene, int max_depth, int rr_depth, bool continuations)
        : scene_(scene), steps_(scene, max_depth, rr_depth), depth_(max_depth), continuations_(continuations) {}

    bool continuations() const { return continuations_; }

    // Path p's ray ended on triangle `tri` at distance t_hit, barycentrics (u, v) (tri < 0: it
    // escaped). Its jobs go to segment_job and surface_job (each set at most once; `made` says
    // which); p moves on, or ends (p.alive).
    struct Jobs {
        GatherJob segment, surface;
        bool has_segment = false, has_surface = false;
        TransmittanceTrack track;  // the segment's, in a grid
    };
    void step(GatherCameraPath &p, int64_t path, int tri, double t_hit, double u, double v, MediumStats &stats,
              Jobs &jobs) const {
        jobs.has_segment = jobs.has_surface = false;
        if (p.medium >= 0) {
            const Medium &m = scene_.media[size_t(p.medium)];
            const double length = tri >= 0 ? t_hit + p.lead : kInf;
            const Vec3 origin = segment_origin(p);
            if (p.gathering && depth_.allows(p.depth + 1)) {
                GatherJob &j = jobs.segment;
                j.at = GatherPoint{origin, -p.dir, -1, p.medium};
                j.length = length;
                j.weight = p.throughput;
                j.path = path;
                j.events = int16_t(p.depth + 1);
                j.rng = p.rng.fork();
                if (m.type == MediumType::Grid) {
                    Sampler walk = j.rng.split(0x747261636bull);  // "track"
                    jobs.track = TransmittanceTrack(m, origin, p.dir, std::isfinite(length) ? length : 1e30, walk,
                                                    stats);
                }
                jobs.has_segment = true;
            }
            if (p.gathering && continuations_) {
                // A collision before the surface continues from there, looking for specular
                // chains; passing it reaches the surface with weight Tr / P(pass).
                const FreeFlight ff = sample_free_flight(m, origin, p.dir, length, p.rng, stats, p.spectral);
                p.throughput *= ff.weight;
                if (ff.scattered) {
                    if (!steps_.count_event(p)) return;
                    advance_by_phase(m, p, segment_point(p, ff.t));
                    p.gathering = false;
                    p.alive = steps_.russian_roulette(p);
                    return;
                }
            } else if (tri >= 0) {
                if (m.type == MediumType::Homogeneous) {
                    p.throughput *= beer_lambert(m.sigma_t, length);
                } else {
                    Sampler rng = p.rng.fork();
                    p.throughput *= transmittance(m, origin, p.dir, length, rng, stats);
                }
            }
            if (is_black(p.throughput)) {
                p.alive = false;
                return;
            }
        }
        if (tri < 0) {  // escaped: the scenes have no environment light
            p.alive = false;
            return;
        }
        const Triangle &T = scene_.triangles[size_t(tri)];
        const Material &mat = scene_.materials[size_t(T.material)];
        const Vec3 x = T.point(u, v);
        if (p.gathering && depth_.allows(p.depth)) p.radiance += p.throughput * scene_.emitted(tri, p.dir);
        if (mat.type == MaterialType::Null) {
            cross_null_boundary(scene_, p, tri, x);
            return;
        }
        if (!mat.is_delta()) {
            if (!p.gathering || !steps_.count_event(p)) {  // a continuing path's next vertex: made
                p.alive = false;
                return;
            }
            if (dot(p.dir, T.n) < 0) {  // seen from the front of a one-sided surface
                GatherJob &j = jobs.surface;
                j.at = GatherPoint{x, -p.dir, tri, p.medium};
                j.weight = p.throughput;
                j.path = path;
                j.events = int16_t(p.depth);
                j.rng = p.rng.fork();
                jobs.has_surface = true;
            }
            if (!continuations_) {
                p.alive = false;
                return;
            }
            steps_.continue_by_bsdf(p, tri, x);
            p.gathering = false;
            return;
        }
        // Specular: follow, gathering again after it.
        if (!steps_.count_event(p)) return;
        steps_.continue_by_bsdf(p, tri, x);
        p.gathering = true;
    }

private:
    const Scene &scene_;
    CameraPathSteps steps_;
    DepthLimit depth_;
    bool continuations_;
};

// Whether some surface of the scene is specular (a mirror or a dielectric): then camera paths
// of gathering methods continue past their gather points (GatherWalk).
inline bool has_specular_surfaces(const Scene &scene) {
    for (const Triangle &t : scene.triangles) {
        const Material &m = scene.materials[size_t(t.material)];
        if (m.is_delta() && m.type != MaterialType::Null) return true;
    }
    return false;
}

// Every (job, light) pair as a shadow ray, streamed in chunks of a fixed number of pairs (see the
// top of this file). Each job has the same number of pairs, `per_job`: pair p is the
// (p % per_job)-th of job p / per_job (which light that is, the kernel says).
class ConnectionStream {
public:
    explicit ConnectionStream(size_t chunk_pairs) : chunk_(std::max<size_t>(1, chunk_pairs)) {}

    // A new set of pairs; the previous one must have been written out to its end.
    void start(int64_t jobs, int64_t per_job) {
        jobs_ = jobs;
        per_job_ = std::max<int64_t>(1, per_job);
        total_ = per_job > 0 ? jobs * per_job : 0;
        cursor_ = first_ = 0;
        queue_.clear();
    }
    int64_t pairs() const { return total_; }
    size_t slots() const { return chunk_; }
    // The pairs of a chunk (between iterations: the values' order and sums do not change with it).
    void set_chunk(size_t chunk_pairs) { chunk_ = std::max<size_t>(1, chunk_pairs); }
    uint64_t rays_aimed() const { return rays_aimed_; }

    // Writes the next shadow-ray segments into `out`; when a chunk is done, adds its values to
    // their jobs (add(job, value), in pair order) and opens the next, whose pairs aim(job, k,
    // ray, stats) fills (the job's k-th pair; setting ray.live and its contribution), in
    // parallel. Returns 0 when every pair is done.
    // aim may count density lookups in its MediumStats (summed into `stats`).
    template <typename Aim, typename Add>
    size_t write(const RayBuffers &out, int threads, MediumStats &stats, Aim &&aim, Add &&add) {
        for (;;) {
            if (const size_t n = queue_.compact_and_write(out, threads)) return n;
            flush(add);
            if (cursor_ >= total_) return 0;
            open(threads, stats, aim);
        }
    }
    void resolve(const Scene &scene, const Hits &hits, int threads, MediumStats &stats) {
        queue_.resolve(scene, hits, threads, stats, [&](int64_t slot, const RGB &value) {
            values_[size_t(slot)] = value;  // one ray per slot: no race
        });
    }

private:
    template <typename Aim>
    void open(int threads, MediumStats &stats, Aim &aim) {
        const size_t n = size_t(std::min<int64_t>(int64_t(chunk_), total_ - cursor_));
        first_ = cursor_;
        cursor_ += int64_t(n);
        queue_.open(n);
        values_.assign(n, RGB(0.0));
        uint64_t aimed = 0;
        MediumStats local;
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads) reduction(+ : aimed, local)
        for (int64_t k = 0; k < int64_t(n); ++k) {
            const int64_t pair = first_ + k;
            ShadowRay &r = queue_[size_t(k)];
            r.live = false;
            aim(pair / per_job_, pair % per_job_, r, local);
            if (r.live) {
                r.receiver = k;
                ++aimed;
            }
        }
        rays_aimed_ += aimed;
        stats += local;
    }
    template <typename Add>
    void flush(Add &add) {
        for (size_t k = 0; k < values_.size(); ++k)
            if (!is_black(values_[k])) add((first_ + int64_t(k)) / per_job_, values_[k]);
        values_.clear();
        queue_.clear();
    }

    size_t chunk_;
    int64_t jobs_ = 0, per_job_ = 1, total_ = 0, cursor_ = 0, first_ = 0;
    ShadowQueue queue_;
    std::vector<RGB> values_;
    uint64_t rays_aimed_ = 0;
};

}  // namespace pgi
