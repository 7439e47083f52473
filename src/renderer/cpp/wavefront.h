// Machinery every wavefront method shares: the ray-buffer layout handed to
// Embree, the queue of shadow (connection) rays that cross null boundaries
// and media on their way, and the float64 film.
#pragma once

#include <omp.h>

#include <vector>

#include "scene.h"

namespace pgi {

constexpr float kFarDistance = 1e30f;

// Ray buffers owned by Python: origins (n, 3), directions (n, 3), tmax (n).
struct RayBuffers {
    float *org = nullptr, *dir = nullptr, *tmax = nullptr;
    size_t capacity = 0;
    void put(size_t k, const Vec3 &o, const Vec3 &d, double t) const {
        org[3 * k] = float(o.x); org[3 * k + 1] = float(o.y); org[3 * k + 2] = float(o.z);
        dir[3 * k] = float(d.x); dir[3 * k + 1] = float(d.y); dir[3 * k + 2] = float(d.z);
        tmax[k] = std::isfinite(t) ? float(t) : kFarDistance;
    }
};

// Hits returned by Embree for a batch: prim < 0 means no hit.
struct Hits {
    const float *tfar = nullptr, *u = nullptr, *v = nullptr;
    const int32_t *prim = nullptr;
    size_t count = 0;
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
    int64_t receiver = 0;     // what receives the contribution (a path or a pixel)
    RGB contribution;
    Sampler rng;
    bool live = false;
    // Distance left along dir; origins move off surfaces, so it is measured, not tracked.
    double remaining() const { return to_infinity ? kInf : dot(target - origin, dir); }
    // Start at p (already offset off a surface), pointing exactly at the target: an
    // offset origin with the old direction would pass beside the target and could
    // hit the light's own surface at grazing angles.
    void restart_at(const Vec3 &p) {
        origin = p;
        if (!to_infinity) dir = normalize(target - origin);
    }
};

class ShadowQueue {
public:
    std::vector<ShadowRay> rays;  // one slot per work item; finished rays are dropped by compaction

    void clear() { rays.clear(); }
    // Makes n empty slots; a kernel fills slot k for work item k (or leaves it dead).
    void reset(size_t n) { rays.resize(n); }
    ShadowRay &operator[](size_t k) { return rays[k]; }
    size_t live() const {
        size_t n = 0;
        for (const ShadowRay &r : rays) n += r.live;
        return n;
    }
    // Drops finished rays (keeping order) and writes the rest to the buffers.
    size_t compact_and_write(const RayBuffers &buf, int threads = 1) {
        size_t n = 0;
        for (size_t i = 0; i < rays.size(); ++i)
            if (rays[i].live) {
                if (n != i) rays[n] = rays[i];
                ++n;
            }
        rays.resize(n);
#pragma omp parallel for schedule(static) num_threads(threads)
        for (int64_t k = 0; k < int64_t(n); ++k) {
            const ShadowRay &r = rays[k];
            buf.put(k, r.origin, r.dir, r.remaining() - r.target_eps);
        }
        return n;
    }
    // Advances each ray by one traced segment; deliver(target, value) receives
    // contributions of rays that reached their target unoccluded.
    template <typename Deliver>
    void resolve(const Scene &scene, const Hits &hits, int threads, MediumStats &stats, Deliver &&deliver) {
        MediumStats counts;
#pragma omp parallel for schedule(static) num_threads(threads) reduction(+ : counts)
        for (int64_t k = 0; k < int64_t(rays.size()); ++k) {
            ShadowRay &r = rays[k];
            double remaining = r.remaining();
            bool blocked = hits.prim[k] >= 0 && hits.tfar[k] < remaining - r.target_eps;
            double t = blocked ? double(hits.tfar[k]) : remaining;
            if (r.medium >= 0) {
                r.contribution *= transmittance(scene.media[r.medium], r.origin, r.dir, t, r.rng, counts);
            }
            if (!blocked) {
                r.live = false;
                if (!is_black(r.contribution)) deliver(r.receiver, r.contribution);
                continue;
            }
            int tri = hits.prim[k];
            const Triangle &T = scene.triangles[tri];
            if (scene.materials[T.material].type != MaterialType::Null || is_black(r.contribution)) {
                r.live = false;  // occluded
                continue;
            }
            Vec3 p = r.origin + r.dir * t;
            r.medium = T.medium_after(r.medium, r.dir);
            r.restart_at(scene.offset(p, tri, r.dir));
        }
        stats += counts;
    }
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
