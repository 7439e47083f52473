// lt: light tracing (see lt.h).
#include "lt.h"

namespace pgi {

LightTracing::LightTracing(std::shared_ptr<const Scene> scene, std::shared_ptr<const LightPaths> light_paths,
                           uint64_t seed, int threads)
    : scene_(std::move(scene)), light_paths_(std::move(light_paths)), seed_(seed), threads_(std::max(1, threads)),
      film_(scene_->camera.width, scene_->camera.height) {}

void LightTracing::begin(int64_t iteration) {
    const LightPaths &paths = *light_paths_;
    if (paths.iteration() != iteration)
        throw std::logic_error("lt: the light paths of iteration " + std::to_string(iteration) + " come first");
    const Scene &scene = *scene_;
    const Camera &cam = scene.camera;
    const std::vector<PathVertex> &verts = paths.vertices();
    const double inv_paths = 1.0 / double(paths.paths_per_iteration());
    splats_.assign(verts.size(), Splat());
    shadow_.open(verts.size());
    light_paths_traced_ += uint64_t(paths.paths_per_iteration());
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (int64_t k = 0; k < int64_t(verts.size()); ++k) {
        const PathVertex &v = verts[k];
        ShadowRay &r = shadow_[k];
        r.live = false;
        CameraConnection c = connect_to_camera(cam, v.pos);
        if (!c.valid) continue;
        RGB f(0.0);
        RayStart origin{v.pos};
        int medium = v.medium;
        switch (v.kind) {
            case VertexKind::Emission: {  // one-sided emitter: Le cos / pdf_A
                double cos_l = dot(v.wi, c.to_camera);
                if (cos_l <= 0) continue;
                f = RGB(cos_l);
                origin = scene.spawn(v.pos, v.triangle, c.to_camera);
                break;
            }
            case VertexKind::Surface: {
                const Triangle &T = scene.triangles[v.triangle];
                f = bsdf_eval(scene.materials[T.material], T.n, v.wi, c.to_camera);
                origin = scene.spawn(v.pos, v.triangle, c.to_camera);
                medium = T.medium_after(v.medium, c.to_camera);
                break;
            }
            case VertexKind::Medium:
                f = RGB(phase_eval(scene.media[v.medium].phase, v.wi, c.to_camera));
                break;
        }
        RGB value = v.throughput * f * (c.importance * inv_paths);
        if (is_black(value)) continue;
        splats_[k].pixel = c.pixel;
        r.dir = -c.to_camera;  // placeholder; restart_at aims at the target
        r.target = cam.origin;
        r.to_infinity = false;
        // A boundary within an offset of the camera counts as reached: with the camera on a
        // null boundary the ray would cross it, turn back at the camera, and cross again.
        r.target_eps = scene.offset_length(cam.origin);
        r.restart_at(origin);
        r.medium = medium;
        r.receiver = k;
        r.contribution = value;
        r.rng = Sampler(stream_key(seed_ ^ stream_tag::kConnections, uint64_t(iteration), uint64_t(k)));
        r.live = true;
    }
}

size_t LightTracing::shadow_rays(const RayBuffers &out) {
    return shadow_.compact_and_write(out, threads_);
}

void LightTracing::resolve_shadows(const Hits &hits) {
    shadow_.resolve(*scene_, hits, threads_, stats_, [&](int64_t k, const RGB &value) {
        splats_[k].value += value;  // one connection per vertex: no race
    });
}

void LightTracing::end() {
    for (const Splat &s : splats_)
        if (s.pixel >= 0 && !is_black(s.value)) film_.add(s.pixel, s.value);
    film_.samples_per_pixel += 1;  // the image is the mean of the iterations' estimates
    splats_.clear();
    shadow_.clear();
}

}  // namespace pgi
