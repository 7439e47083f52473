#include "pt.h"

#include <numeric>

namespace pgi {

// A lane claims this many paths of the wave at a time: neighbouring pixels, whose camera
// rays are coherent, and few enough atomic claims that the lanes do not contend.
constexpr int64_t kClaimedPaths = 256;

PathTracing::PathTracing(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed,
                         int spp_per_wave, int lanes, int slots_per_lane)
    : scene_(std::move(scene)), steps_(*scene_, max_depth, rr_depth), depth_(max_depth), seed_(seed),
      spp_per_wave_(std::max(1, spp_per_wave)), film_(scene_->camera.width, scene_->camera.height) {
    wave_paths_ = int64_t(film_.width) * film_.height * spp_per_wave_;
    radiance_.resize(size_t(wave_paths_));
    for (int i = 0; i < std::max(1, lanes); ++i)
        lanes_.push_back(std::make_unique<PathTracingLane>(*this, size_t(std::max(1, slots_per_lane))));
}

PathTracingLane &PathTracing::lane(int i) {
    if (i < 0 || i >= lanes()) throw std::out_of_range("pt: no lane " + std::to_string(i));
    return *lanes_[size_t(i)];
}

void PathTracing::begin(int64_t iteration) {
    iteration_ = iteration;
    std::fill(radiance_.begin(), radiance_.end(), RGB(0.0));
    // Mitsuba: max_depth 0 renders black; the wave then has no path to trace.
    next_path_.store(depth_.allows(0) ? 0 : wave_paths_);
    for (auto &l : lanes_) l->reset();
}

int64_t PathTracing::claim(int64_t count, int64_t &n) {
    int64_t first = next_path_.fetch_add(count, std::memory_order_relaxed);
    n = std::max<int64_t>(0, std::min(count, wave_paths_ - first));
    return first;
}

void PathTracing::end() {
    const int64_t npix = int64_t(film_.width) * film_.height;
    for (int64_t i = 0; i < wave_paths_; ++i) film_.add(i % npix, radiance_[size_t(i)]);
    film_.samples_per_pixel += uint64_t(spp_per_wave_);
    for (auto &l : lanes_) {
        stats_ += l->stats_;
        l->stats_ = MediumStats{};
    }
}

PathTracingLane::PathTracingLane(PathTracing &owner, size_t slots)
    : owner_(owner), slots_(slots), path_of_slot_(slots, -1) {}

const Scene &PathTracingLane::scene() const { return *owner_.scene_; }

void PathTracingLane::reset() {
    active_.resize(slots_.size());
    std::iota(active_.begin(), active_.end(), 0);
    std::fill(path_of_slot_.begin(), path_of_slot_.end(), -1);
    for (CameraPath &p : slots_) p.alive = false;
    shadow_.clear();
    stats_ = MediumStats{};  // a wave cut short counts for nothing
    claimed_ = claimed_end_ = 0;
}

size_t PathTracingLane::next_rays(const RayBuffers &out) {
    PathTracing &pt = owner_;
    const Camera &cam = pt.scene_->camera;
    if (out.capacity < active_.size()) throw std::invalid_argument("pt next_rays: ray buffers too small");
    size_t kept = 0;
    for (size_t j = 0; j < active_.size(); ++j) {  // in place: kept <= j
        const int32_t s = active_[j];
        CameraPath &p = slots_[size_t(s)];
        if (p.alive) {
            out.put(kept, p.pos, p.dir, kInf);
            active_[kept++] = s;
            continue;
        }
        int64_t &path = path_of_slot_[size_t(s)];
        if (path >= 0) pt.radiance_[size_t(path)] = p.radiance;  // only this slot held it
        path = -1;
        if (claimed_ == claimed_end_) {
            int64_t n;
            claimed_ = pt.claim(kClaimedPaths, n);
            claimed_end_ = claimed_ + n;
            if (n == 0) continue;  // the wave has no path left to start
        }
        path = claimed_++;
        start_camera_sample(p, cam, path, pt.iteration_, pt.spp_per_wave_, pt.seed_);
        out.put(kept, p.pos, p.dir, kInf);
        active_[kept++] = s;
    }
    active_.resize(kept);
    return kept;
}

size_t PathTracingLane::shade(const Hits &hits) {
    const Scene &scene = *owner_.scene_;
    const CameraPathSteps &steps = owner_.steps_;
    hits.expect(active_.size(), "pt shade");
    shadow_.open(hits.count);
    for (size_t k = 0; k < hits.count; ++k) {
        const int32_t slot = active_[k];
        CameraPath &p = slots_[size_t(slot)];
        ShadowRay &shadow = shadow_[k];
        shadow.live = false;
        int tri = hits.prim[k];
        double t_hit = tri >= 0 ? double(hits.tfar[k]) : kInf;

        // Medium: a real collision before the surface scatters the path there.
        if (p.medium >= 0 && steps.fly_through_medium(p, shadow, slot, t_hit, stats_)) continue;
        Vec3 x;
        if (!steps.reach_surface(p, tri, hits.u[k], hits.v[k], x)) continue;
        const Material &mat = scene.materials[scene.triangles[tri].material];
        if (!steps.count_event(p)) continue;
        if (!mat.is_delta()) steps.next_event_on_surface(p, shadow, slot, tri, x);
        steps.continue_by_bsdf(p, tri, x);
    }
    return shadow_.live();
}

void PathTracingLane::resolve_shadows(const Hits &hits) {
    shadow_.resolve(*owner_.scene_, hits, 1, stats_, [&](int64_t slot, const RGB &value) {
        slots_[size_t(slot)].radiance += value;
    });
}

}  // namespace pgi
