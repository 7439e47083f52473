// direct: direct lighting at the first surface a camera ray meets, in scenes without media.
// The worked example of docs/methods.md ("Adding a method"): the smallest kernel that follows
// the iteration protocol of passes.h with every pass (camera rays, shading, shadow rays), made
// of the shared steps of camera_path.h. It is not one of the study's methods.
//   Veach 1997, "Robust Monte Carlo methods for light transport simulation", ch. 9.
//
// The estimator, per camera sample through the pixel (box filter):
//   L = L_e(x_1 -> camera) + f(x_1) L_e(y) G(x_1, y) V(x_1, y) / p_light(y)
// where x_1 is the first surface the ray meets past null boundaries (black if it is a delta
// BSDF), and y a point sampled on a light by Scene::sample_light (no MIS: nothing else samples
// the light's contribution here). With max_depth 2 this is pt's image without media.
//
// Passes: begin starts one camera path per pixel sample; next_rays writes the rays of the paths
// in flight; shade adds the emission a ray finds, crosses null boundaries, and at a scattering
// surface queues one shadow ray to a light sample and ends the path; resolved shadow rays add
// their value to their path; end adds each path's radiance to its pixel in path order.
#pragma once

#include <memory>

#include "camera_path.h"
#include "passes.h"

namespace pgi {

class DirectLighting : public SingleLane<DirectLighting> {
public:
    DirectLighting(std::shared_ptr<const Scene> scene, int max_depth, uint64_t seed, int spp_per_iteration,
                   int threads)
        : scene_(std::move(scene)), steps_(*scene_, max_depth, /*rr_depth=*/0), depth_(max_depth), seed_(seed),
          spp_(std::max(1, spp_per_iteration)), threads_(std::max(1, threads)),
          film_(scene_->camera.width, scene_->camera.height) {
        paths_.resize(size_t(film_.width) * film_.height * spp_);
    }

    void begin(int64_t iteration) {
        active_.clear();
        shadow_.clear();
        if (depth_.allows(0)) start_camera_wave(paths_, active_, scene_->camera, iteration, spp_, seed_, threads_);
    }
    size_t next_rays(const RayBuffers &out) { return write_alive_rays(active_, paths_, out, threads_); }
    size_t shade(const Hits &hits) {
        hits.expect(active_.size(), "direct shade");
        shadow_.open(hits.count);
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads_)
        for (int64_t k = 0; k < int64_t(hits.count); ++k) {
            CameraPath &p = paths_[active_[k]];
            shadow_[k].live = false;
            Vec3 x;
            const int tri = hits.prim[k];
            if (!steps_.reach_surface(p, tri, hits.u[k], hits.v[k], x)) continue;  // emission added
            const bool delta = scene_->materials[scene_->triangles[tri].material].is_delta();
            if (!delta && steps_.count_event(p))
                steps_.next_event_on_surface(p, shadow_[k], active_[k], tri, x, /*mis=*/false);
            p.alive = false;  // the path ends at its first scattering surface
        }
        return shadow_.live(threads_);
    }
    size_t shadow_slots() const { return shadow_.opened(); }
    size_t shadow_rays(const RayBuffers &out) { return shadow_.compact_and_write(out, threads_); }
    void resolve_shadows(const Hits &hits) {
        shadow_.resolve(*scene_, hits, threads_, stats_, [&](int64_t path, const RGB &value) {
            paths_[size_t(path)].radiance += value;  // one shadow ray per path: no race
        });
    }
    void end() { add_paths_to_film(film_, paths_, spp_); }

    size_t capacity() const { return paths_.size(); }
    const Scene &scene() const { return *scene_; }
    const Film &film() const { return film_; }
    uint64_t density_lookups() const { return stats_.density_lookups; }

private:
    std::shared_ptr<const Scene> scene_;
    CameraPathSteps steps_;
    DepthLimit depth_;
    uint64_t seed_;
    int spp_, threads_;
    std::vector<CameraPath> paths_;
    std::vector<int32_t> active_;
    ShadowQueue shadow_;
    Film film_;
    MediumStats stats_;
};

}  // namespace pgi
