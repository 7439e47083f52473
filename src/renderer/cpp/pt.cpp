#include "pt.h"

namespace pgi {

PathTracer::PathTracer(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed,
                       int spp_per_wave, int threads)
    : scene_(std::move(scene)), steps_(*scene_, max_depth, rr_depth), max_depth_(max_depth), seed_(seed), spp_per_wave_(std::max(1, spp_per_wave)),
      threads_(std::max(1, threads)), film_(scene_->camera.width, scene_->camera.height) {
    paths_.resize(size_t(film_.width) * film_.height * spp_per_wave_);
}

size_t PathTracer::begin_wave(int64_t iteration, const RayBuffers &out) {
    const Camera &cam = scene_->camera;
    active_.clear();
    shadow_.clear();
    if (max_depth_ == 0) return 0;  // Mitsuba: max_depth 0 renders black
    start_camera_wave(paths_, active_, cam, iteration, spp_per_wave_, seed_, out, threads_);
    paths_traced_ += paths_.size();
    return active_.size();
}

size_t PathTracer::shade(const Hits &hits) {
    const Scene &scene = *scene_;
    hits.expect(active_.size(), "pt shade");
    MediumStats counts;
    shadow_.open(hits.count);
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads_) reduction(+ : counts)
    for (int64_t k = 0; k < int64_t(hits.count); ++k) {
        const int64_t index = active_[k];
        CameraPath &p = paths_[index];
        ShadowRay &shadow = shadow_[k];
        shadow.live = false;
        int tri = hits.prim[k];
        double t_hit = tri >= 0 ? double(hits.tfar[k]) : kInf;

        // Medium: a real collision before the surface scatters the path there.
        if (p.medium >= 0) {
            FreeFlight ff =
                sample_free_flight(scene.media[p.medium], segment_origin(p), p.dir, t_hit + p.lead, p.rng, counts);
            p.throughput *= ff.weight;
            if (ff.scattered) {
                steps_.scatter_in_medium(p, shadow, index, segment_point(p, ff.t));
                continue;
            }
        }
        Vec3 x;
        if (!steps_.reach_surface(p, tri, hits.u[k], hits.v[k], x)) continue;
        const Material &mat = scene.materials[scene.triangles[tri].material];
        if (!steps_.count_event(p)) continue;
        if (!mat.is_delta()) steps_.next_event_on_surface(p, shadow, index, tri, x);
        steps_.continue_by_bsdf(p, tri, x);
    }
    stats_ += counts;
    return shadow_.live(threads_);
}

void PathTracer::resolve_shadows(const Hits &hits) {
    shadow_.resolve(*scene_, hits, threads_, stats_, [&](int64_t path, const RGB &value) {
        paths_[path].radiance += value;  // one shadow ray per path at a time: no race
    });
}

size_t PathTracer::next_rays(const RayBuffers &out) { return write_alive_rays(active_, paths_, out, threads_); }

void PathTracer::end_wave() {
    add_paths_to_film(film_, paths_, spp_per_wave_);
    active_.clear();
}

}  // namespace pgi
