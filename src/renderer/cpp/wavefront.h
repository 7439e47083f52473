// Machinery every wavefront method shares: the steps any path (camera or light)
// takes at a surface, the ray-buffer layout handed to Embree, the queue of shadow
// (connection) rays that cross null boundaries and media on their way, and the
// float64 film.
#pragma once

#include <omp.h>

#include <numeric>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "scene.h"

namespace pgi {

constexpr float kFarDistance = 1e30f;

// A path that has crossed this many null boundaries is trapped (e.g. between
// coincident faces) and ends.
constexpr int kMaxNullCrossings = 256;

// A path's next ray starts at p.pos; its medium segment starts p.lead behind it, on the
// surface the path leaves (RayStart). Set the path's direction first.
template <typename Path>
void start_path_at(Path &p, const RayStart &start) {
    p.pos = start.origin;
    p.lead = start.lead;
}
// A vertex inside a medium (or a camera or light in open space): no surface behind it.
template <typename Path>
void start_path_at(Path &p, const Vec3 &x) {
    p.pos = x;
    p.lead = 0;
}
template <typename Path>
Vec3 segment_origin(const Path &p) {
    return p.pos - p.dir * p.lead;
}
// The point at distance t along the medium segment. One in the lead lies nearer the surface
// than an offset; it still starts its own rays from where it is: moving it out to p.pos
// would darken a medium whose mean free path is shorter than an offset, as skipping did.
template <typename Path>
Vec3 segment_point(const Path &p, double t) {
    return p.pos + p.dir * (t - p.lead);
}

// An index-matched (null) boundary at x on triangle `tri`: the path changes medium
// and keeps its direction, depth and MIS state. Crossings count over the whole path.
template <typename Path>
void cross_null_boundary(const Scene &scene, Path &p, int tri, const Vec3 &x) {
    p.medium = scene.triangles[tri].medium_after(p.medium, p.dir);
    start_path_at(p, scene.spawn(x, tri, p.dir));
    p.alive = ++p.null_crossings < kMaxNullCrossings;
}

// The BSDF step of every path at a scattering surface x on triangle `tri`: samples the BSDF
// for wo = -p.dir from three uniforms of the path's stream and, if the sample is valid,
// multiplies `carried` (a camera path's throughput, a light path's power) by its weight and
// sends the path along wi: the medium on that side, the next ray off the surface. `radiance`
// is the transport bsdf_sample scales refraction for (false: a light path's importance). An
// invalid sample ends the path. What differs by path stays with the caller: the MIS state,
// eta^2 or the specular flag kept from the sample, and Russian roulette.
template <typename Path>
BsdfSample advance_by_bsdf(const Scene &scene, Path &p, RGB &carried, int tri, const Vec3 &x, bool radiance) {
    const Triangle &T = scene.triangles[tri];
    double u1 = p.rng.next(), u2 = p.rng.next(), u3 = p.rng.next();
    BsdfSample bs = bsdf_sample(scene.materials[T.material], T.n, -p.dir, u1, u2, u3, radiance);
    if (!bs.valid) {
        p.alive = false;
        return bs;
    }
    carried *= bs.weight;
    p.dir = bs.wi;
    p.medium = T.medium_after(p.medium, bs.wi);
    start_path_at(p, scene.spawn(x, tri, bs.wi));
    return bs;
}

// The phase step of every path at a real collision x in medium m: a direction for
// wo = -p.dir sampled exactly (phase functions are symmetric, so the weight is 1 for
// radiance and importance alike), and the path's next ray from x. Returns the sample's
// solid-angle pdf; the MIS state and flags kept from it stay with the caller.
template <typename Path>
double advance_by_phase(const Medium &m, Path &p, const Vec3 &x) {
    double pdf, u1 = p.rng.next(), u2 = p.rng.next();
    p.dir = phase_sample(m.phase, -p.dir, u1, u2, pdf);
    start_path_at(p, x);
    return pdf;
}

// Russian roulette's draw for every path (camera and light paths alike): the path goes on with
// probability q (its throughput, or its power relative to what it was emitted with) and
// `carried` is divided by it. Under the scene's rule (scene.h, Roulette):
//   Throughput  q capped at 1 (pbrt-v4): a path that carries at least what it started with
//               always goes on, and a survivor carries 1 at most, so weights stay bounded
//               however many events a path takes (a white cloud: thousands);
//   Mitsuba     q capped at 0.95 (Mitsuba's volpath): every event past rr_depth costs 5 %, so
//               a path of n such events that survives carries 0.95^-n: in white, dense media
//               the estimate's variance explodes (e^82 after 1600 events).
inline bool survive_roulette(RGB &carried, double q, Sampler &rng, Roulette rule) {
    if (rule == Roulette::Mitsuba) {
        q = std::min(q, 0.95);
    } else if (q >= 1) {
        return true;
    }
    if (!(rng.next() < q)) return false;
    carried = carried / q;
    return true;
}

// Ray buffers owned by Python: origins (n, 3), directions (n, 3), tmax (n).
struct RayBuffers {
    float *org = nullptr, *dir = nullptr, *tmax = nullptr;
    size_t capacity = 0;
    void put(size_t k, const Vec3 &o, const Vec3 &d, double t) const {
        org[3 * k] = float(o.x); org[3 * k + 1] = float(o.y); org[3 * k + 2] = float(o.z);
        dir[3 * k] = float(d.x); dir[3 * k + 1] = float(d.y); dir[3 * k + 2] = float(d.z);
        // A shadow ray that starts within target_eps of its target has t < 0: Embree
        // deactivates such rays, and its occlusion query would then report them blocked.
        tmax[k] = std::isfinite(t) ? float(std::max(0.0, t)) : kFarDistance;
    }
};

// Hits returned by Embree for a batch: prim < 0 means no hit. Shadow rays of a
// scene without null boundaries may come from an occlusion query instead
// (any_hit): prim >= 0 then only says that something blocks the segment.
struct Hits {
    const float *tfar = nullptr, *u = nullptr, *v = nullptr;
    const int32_t *prim = nullptr;
    size_t count = 0;
    bool any_hit = false;
    // Hit k belongs to ray k of the batch the kernel wrote: the counts must agree.
    void expect(size_t rays, const char *pass) const {
        if (count != rays)
            throw std::invalid_argument(std::string(pass) + ": " + std::to_string(count) + " hits for " +
                                        std::to_string(rays) + " rays");
    }
};

// A connection towards a light point (or the camera) whose contribution is
// known up to visibility and transmittance. It is traced segment by segment
// through null boundaries; media along the way multiply it by transmittance.
struct ShadowRay {
    Vec3 origin, dir;
    Vec3 target;              // point to reach (unused when it lies at infinity)
    bool to_infinity = false; // directional lights
    double target_eps = 0;    // stop this short of the target (it lies on a surface)
    int medium = -1;
    double lead = 0;          // medium behind the origin (RayStart)
    int64_t receiver = 0;     // what receives the contribution (a path or a pixel)
    RGB contribution;
    double tau = 0;           // queues that track flights: the stand-in optical depth so far
    Sampler rng;
    bool live = false;
    // Distance left along dir; origins move off surfaces, so it is measured, not tracked.
    double remaining() const { return to_infinity ? kInf : dot(target - origin, dir); }
    // Start at `start` (offset off a surface, or a vertex), pointing exactly at the target: an
    // offset origin with the old direction would pass beside the target and could
    // hit the light's own surface at grazing angles.
    void restart_at(const RayStart &start) {
        origin = start.origin;
        lead = start.lead;
        if (!to_infinity) dir = normalize(target - origin);
    }
};

// Keeps, in order, the entries of `items` for which keep(entry) holds and calls
// emit(position, entry) for each kept one. Chunks run on `threads` threads:
// each compacts its own chunk, then all move them to their final offsets.
template <typename Keep, typename Emit>
size_t compact_in_order(std::vector<int32_t> &items, int threads, Keep &&keep, Emit &&emit) {
    // Scratch reused between calls (per calling thread; the team shares the caller's).
    static thread_local std::vector<int32_t> scratch;
    std::vector<int32_t> &kept = scratch;
    const int64_t n = int64_t(items.size());
    kept.resize(items.size());
    std::vector<int64_t> offsets(size_t(std::max(1, threads)) + 1, 0);
    int teams = 1;
#pragma omp parallel num_threads(std::max(1, threads))
    {
        const int t = omp_get_thread_num(), nt = omp_get_num_threads();
        if (t == 0) teams = nt;
        const int64_t lo = n * t / nt, hi = n * (t + 1) / nt;
        int64_t end = lo;
        for (int64_t i = lo; i < hi; ++i)
            if (keep(items[i])) kept[end++] = items[i];
        offsets[t + 1] = end - lo;
#pragma omp barrier
#pragma omp single
        for (int i = 0; i < nt; ++i) offsets[i + 1] += offsets[i];
        // Every read of `items` happened before the barriers above.
        for (int64_t i = lo; i < end; ++i) {
            int64_t position = offsets[t] + (i - lo);
            items[position] = kept[i];
            emit(position, kept[i]);
        }
    }
    const size_t total = size_t(offsets[size_t(teams)]);
    items.resize(total);
    return total;
}

// Keeps the paths still alive (in order) and writes their extension rays: every wave of
// camera or light paths ends its bounce with it.
template <typename Path>
size_t write_alive_rays(std::vector<int32_t> &active, const std::vector<Path> &paths, const RayBuffers &out,
                        int threads) {
    if (out.capacity < active.size()) throw std::invalid_argument("next_rays: ray buffers too small");
    return compact_in_order(
        active, threads, [&](int32_t i) { return paths[i].alive; },
        [&](int64_t k, int32_t i) { out.put(size_t(k), paths[i].pos, paths[i].dir, kInf); });
}

// Shadow rays of one pass, one slot per work item. Slot storage is kept from
// pass to pass and never constructed again (a wave opens tens of thousands of
// slots per bounce): a kernel must set `live` in every slot it opens. Rays
// still travelling are listed by index, so compaction moves 4-byte indices
// instead of rays.
class ShadowQueue {
public:
    // Opens n slots for a kernel to fill (slot k for work item k).
    void open(size_t n) {
        if (slots_.size() < n) slots_.resize(n);
        opened_ = n;
        travelling_.clear();
        listed_ = false;
    }
    void clear() { open(0); }
    size_t opened() const { return opened_; }  // the slots a kernel opened (its shadow_slots)
    ShadowRay &operator[](size_t k) { return slots_[k]; }
    // Live rays: among the opened slots before the first trace, else among those travelling.
    size_t live(int threads = 1) const {
        const int64_t n = listed_ ? int64_t(travelling_.size()) : int64_t(opened_);
        size_t count = 0;
#pragma omp parallel for schedule(static) num_threads(threads) reduction(+ : count)
        for (int64_t j = 0; j < n; ++j) count += slots_[listed_ ? size_t(travelling_[j]) : size_t(j)].live;
        return count;
    }
    // Drops finished rays from the travelling list (keeping slot order) and
    // writes the next segment of the rest to the buffers.
    size_t compact_and_write(const RayBuffers &buf, int threads = 1) {
        if (!listed_) {
            travelling_.resize(opened_);
            std::iota(travelling_.begin(), travelling_.end(), 0);
            listed_ = true;
        }
        if (travelling_.size() > buf.capacity) {  // only then can the live ones overflow
            size_t live = 0;
            for (int32_t k : travelling_) live += slots_[k].live;
            if (live > buf.capacity) throw std::invalid_argument("shadow ray buffers too small");
        }
        return compact_in_order(
            travelling_, threads, [&](int32_t k) { return slots_[k].live; },
            [&](int64_t j, int32_t k) {
                const ShadowRay &r = slots_[k];
                buf.put(size_t(j), r.origin, r.dir, r.remaining() - r.target_eps);
            });
    }
    // Advances each travelling ray by its traced segment (hit j belongs to the
    // j-th travelling ray); deliver(receiver, value) receives the contributions
    // of rays that reached their target unoccluded, deliver(receiver, value, tau) also the
    // stand-in optical depth of the ray's line (densities.h: MIS needs it of a connection) when
    // the queue tracks flights.
    template <typename Deliver>
    void resolve(const Scene &scene, const Hits &hits, int threads, MediumStats &stats, Deliver &&deliver) {
        hits.expect(travelling_.size(), "resolve_shadows");
        if (hits.any_hit && scene.has_null_surfaces)
            throw std::invalid_argument("resolve_shadows: an occlusion query cannot see through null boundaries");
        MediumStats counts;
#pragma omp parallel for schedule(dynamic, 512) num_threads(threads) reduction(+ : counts)
        for (int64_t j = 0; j < int64_t(travelling_.size()); ++j) {
            ShadowRay &r = slots_[travelling_[j]];
            const int tri = hits.prim[j];
            double remaining = r.remaining();
            bool blocked = tri >= 0 && (hits.any_hit || hits.tfar[j] < remaining - r.target_eps);
            // An opaque blocker ends the ray: no transmittance to estimate on the way.
            if (blocked && (hits.any_hit || scene.materials[scene.triangles[tri].material].type != MaterialType::Null)) {
                r.live = false;
                continue;
            }
            double t = blocked ? double(hits.tfar[j]) : remaining;
            if (r.medium >= 0) {
                const Medium &m = scene.media[r.medium];
                r.contribution *= transmittance(m, r.origin - r.dir * r.lead, r.dir, t + r.lead, r.rng, counts);
                if (track_flights_) r.tau += flight_depth(m, r.origin - r.dir * r.lead, r.dir, t + r.lead);
            }
            auto arrive = [&] {
                r.live = false;
                if (is_black(r.contribution)) return;
                if constexpr (std::is_invocable_v<Deliver, int64_t, const RGB &, double>)
                    deliver(r.receiver, r.contribution, r.tau);
                else
                    deliver(r.receiver, r.contribution);
            };
            if (!blocked) {
                arrive();
                continue;
            }
            if (is_black(r.contribution)) {  // nothing left to carry through the boundary
                r.live = false;
                continue;
            }
            const Triangle &T = scene.triangles[tri];
            Vec3 p = r.origin + r.dir * t;
            r.medium = T.medium_after(r.medium, r.dir);
            const Vec3 travelled = r.dir;
            r.restart_at(scene.spawn(p, tri, r.dir));
            // A target (a point in a medium) nearer the boundary than its offset: the restart
            // passed it, and restarting towards it would cross the boundary back and forth
            // for ever. It is reached (the sliver's transmittance is left out).
            if (!r.to_infinity && dot(r.target - r.origin, travelled) <= 0) arrive();
        }
        stats += counts;
    }

    // Whether resolve sums each ray's stand-in optical depth (its kernel sets tau = 0).
    void track_flights(bool on) { track_flights_ = on; }

private:
    std::vector<ShadowRay> slots_;
    std::vector<int32_t> travelling_;  // slots whose rays are still on their way, in order
    bool track_flights_ = false;
    size_t opened_ = 0;
    bool listed_ = false;  // travelling_ has been built since open()
};

// Float64 accumulation of per-pixel estimates; non-finite samples are counted
// and dropped before they can reach the image.
class Film {
public:
    Film(int w, int h) : width(w), height(h), sum(size_t(w) * h * 3, 0.0) {}
    int width, height;
    std::vector<double> sum;
    uint64_t samples_per_pixel = 0;
    uint64_t nonfinite = 0;

    void add(int64_t pixel, const RGB &v) {
        if (!is_finite(v)) {
            ++nonfinite;
            return;
        }
        sum[3 * pixel] += v.x;
        sum[3 * pixel + 1] += v.y;
        sum[3 * pixel + 2] += v.z;
    }
};

}  // namespace pgi
