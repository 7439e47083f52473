#include "pt.h"

namespace pgi {

// Null crossings allowed per path segment chain before we call it trapped.
constexpr int kMaxNullCrossings = 256;

PathTracer::PathTracer(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed,
                       int spp_per_wave, int threads)
    : scene_(std::move(scene)), max_depth_(max_depth), rr_depth_(rr_depth), seed_(seed),
      spp_per_wave_(std::max(1, spp_per_wave)), threads_(std::max(1, threads)),
      film_(scene_->camera.width, scene_->camera.height) {
    paths_.resize(size_t(film_.width) * film_.height * spp_per_wave_);
}

size_t PathTracer::begin_wave(int64_t iteration, const RayBuffers &out) {
    const Camera &cam = scene_->camera;
    const int64_t npix = int64_t(cam.width) * cam.height;
    active_.clear();
    shadow_.clear();
    if (max_depth_ == 0) return 0;  // Mitsuba: max_depth 0 renders black
    active_.resize(paths_.size());
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (int64_t i = 0; i < int64_t(paths_.size()); ++i) {
        CameraPath &p = paths_[i];
        int64_t pixel = i % npix;
        int64_t sample = iteration * spp_per_wave_ + i / npix;
        p = CameraPath();
        p.rng = Sampler(stream_key(seed_, uint64_t(sample), uint64_t(pixel)));
        p.pixel = pixel;
        double fx = double(pixel % cam.width) + p.rng.next();
        double fy = double(pixel / cam.width) + p.rng.next();
        p.pos = cam.origin;
        p.dir = cam.direction(fx, fy);
        p.medium = cam.medium;
        p.alive = true;
        active_[i] = int32_t(i);
        out.put(i, p.pos, p.dir, kInf);
    }
    paths_traced_ += paths_.size();
    return active_.size();
}

size_t PathTracer::shade(const Hits &hits) {
    const Scene &scene = *scene_;
    MediumStats counts;
    shadow_.reset(hits.count);
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads_) reduction(+ : counts)
    for (int64_t k = 0; k < int64_t(hits.count); ++k) {
        CameraPath &p = paths_[active_[k]];
        shadow_[k].live = false;
        int tri = hits.prim[k];
        double t_hit = tri >= 0 ? double(hits.tfar[k]) : kInf;

        // Medium: a real collision before the surface scatters the path there.
        if (p.medium >= 0) {
            FreeFlight ff = sample_free_flight(scene.media[p.medium], p.pos, p.dir, t_hit, p.rng, counts);
            p.throughput *= ff.weight;
            if (ff.scattered) {
                scatter_in_medium(p, k, p.pos + p.dir * ff.t);
                continue;
            }
        }
        if (tri < 0) {  // escaped: the scenes have no environment light
            p.alive = false;
            continue;
        }
        const Triangle &T = scene.triangles[tri];
        Vec3 x = T.point(hits.u[k], hits.v[k]);

        // Emission found by the sampled direction, weighted against light sampling.
        RGB Le = scene.emitted(tri, p.dir);
        if (!is_black(Le)) {
            double w = 1;
            if (!p.prev_delta) w = power_heuristic(p.prev_pdf, scene.area_light_pdf(tri, p.prev_pos, x));
            p.radiance += p.throughput * Le * w;
        }

        if (scene.materials[T.material].type == MaterialType::Null) {
            // Index-matched boundary: change medium, keep direction, depth and MIS state.
            p.medium = T.medium_after(p.medium, p.dir);
            p.pos = scene.offset(x, tri, p.dir);
            p.alive = ++p.null_crossings < kMaxNullCrossings;
            continue;
        }
        scatter_on_surface(p, k, tri, x);
    }
    stats_ += counts;
    return shadow_.live();
}

void PathTracer::queue_shadow(CameraPath &p, size_t slot, const LightSample &ls, const RGB &f,
                              double pdf_dir, const Vec3 &origin, int medium) {
    if (!ls.valid || is_black(f)) return;
    double w = ls.delta ? 1.0 : power_heuristic(ls.pdf, pdf_dir);
    ShadowRay &r = shadow_[slot];
    r.dir = ls.wi;
    r.to_infinity = !std::isfinite(ls.dist);
    r.target = r.to_infinity ? Vec3() : ls.point;
    r.target_eps = r.to_infinity ? 0 : 2 * scene_->offset_length(ls.point);
    r.restart_at(origin);
    r.medium = medium;
    r.contribution = p.throughput * f * ls.value * w;
    r.rng = p.rng.split(uint64_t(p.depth));
    r.live = !is_black(r.contribution);
    r.receiver = int64_t(&p - paths_.data());  // the path gathers it, then the film in order
}

void PathTracer::scatter_in_medium(CameraPath &p, size_t slot, const Vec3 &x) {
    const Medium &m = scene_->media[p.medium];
    if (++p.depth >= max_depth_ && max_depth_ >= 0) {
        p.alive = false;
        return;
    }
    Vec3 wo = -p.dir;
    LightSample ls = scene_->sample_light(x, p.rng);
    if (ls.valid) {
        double f = phase_eval(m.phase, wo, ls.wi);
        queue_shadow(p, slot, ls, RGB(f), f, x, p.medium);
    }
    double pdf;
    double u1 = p.rng.next(), u2 = p.rng.next();
    Vec3 wi = phase_sample(m.phase, wo, u1, u2, pdf);
    // The phase function is sampled exactly, so the weight is 1.
    p.prev_pos = x;
    p.prev_pdf = pdf;
    p.prev_delta = false;
    p.pos = x;
    p.dir = wi;
    p.alive = russian_roulette(p);
}

void PathTracer::scatter_on_surface(CameraPath &p, size_t slot, int tri, const Vec3 &x) {
    const Triangle &T = scene_->triangles[tri];
    const Material &mat = scene_->materials[T.material];
    if (++p.depth >= max_depth_ && max_depth_ >= 0) {
        p.alive = false;
        return;
    }
    Vec3 wo = -p.dir;
    if (!mat.is_delta()) {
        LightSample ls = scene_->sample_light(x, p.rng);
        if (ls.valid) {
            RGB f = bsdf_eval(mat, T.n, wo, ls.wi);
            double pdf = bsdf_pdf(mat, T.n, wo, ls.wi);
            queue_shadow(p, slot, ls, f, pdf, scene_->offset(x, tri, ls.wi), T.medium_after(p.medium, ls.wi));
        }
    }
    double u1 = p.rng.next(), u2 = p.rng.next(), u3 = p.rng.next();
    BsdfSample bs = bsdf_sample(mat, T.n, wo, u1, u2, u3);
    if (!bs.valid) {
        p.alive = false;
        return;
    }
    p.throughput *= bs.weight;
    p.prev_pos = x;
    p.prev_pdf = bs.pdf;
    p.prev_delta = bs.delta;
    p.eta2 *= bs.eta * bs.eta;
    p.dir = bs.wi;
    p.medium = T.medium_after(p.medium, bs.wi);
    p.pos = scene_->offset(x, tri, bs.wi);
    p.alive = russian_roulette(p);
}

// Mitsuba's rule: after rr_depth real bounces, continue with probability
// min(max(throughput) * eta^2, 0.95) and divide by it.
bool PathTracer::russian_roulette(CameraPath &p) {
    if (p.depth <= rr_depth_) return true;
    double q = std::min(max_component(p.throughput) * p.eta2, 0.95);
    if (!(p.rng.next() < q)) return false;
    p.throughput = p.throughput / q;
    return true;
}

void PathTracer::resolve_shadows(const Hits &hits) {
    shadow_.resolve(*scene_, hits, threads_, stats_, [&](int64_t path, const RGB &value) {
        paths_[path].radiance += value;  // one shadow ray per path at a time: no race
    });
}

size_t PathTracer::next_rays(const RayBuffers &out) {
    size_t n = 0;
    for (int32_t i : active_)
        if (paths_[i].alive) active_[n++] = i;
    active_.resize(n);
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (int64_t k = 0; k < int64_t(n); ++k) {
        const CameraPath &p = paths_[active_[k]];
        out.put(k, p.pos, p.dir, kInf);
    }
    return n;
}

void PathTracer::end_wave() {
    for (const CameraPath &p : paths_) film_.add(p.pixel, p.radiance);
    film_.samples_per_pixel += spp_per_wave_;
    active_.clear();
}

}  // namespace pgi
