// pm / sppm gathering kernel (see pm.h).
#include "pm.h"

namespace pgi {

// Specular bounces followed when max_depth is unlimited.
constexpr int kMaxSpecularBounces = 64;

namespace {

// Transmittance from the camera-path vertex to many distances along one ray:
// closed form in homogeneous media; in density grids one ratio-tracking walk
// whose running product up to t estimates Tr(0, t) without bias for every t at once.
class TransmittanceTrack {
public:
    TransmittanceTrack(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Sampler &rng,
                       MediumStats &stats)
        : medium_(m) {
        if (m.type == MediumType::Homogeneous) return;
        ++stats.segments;
        ratio_track(m, o, d, tmax, rng, stats, [&](double t, double tr) { steps_.push_back({t, tr}); });
    }
    RGB at(double t) const {
        if (medium_.type == MediumType::Homogeneous) return beer_lambert(medium_.sigma_t, t);
        // Last step before t.
        size_t lo = 0, hi = steps_.size();
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (steps_[mid].first < t) lo = mid + 1; else hi = mid;
        }
        return RGB(lo == 0 ? 1.0 : steps_[lo - 1].second);
    }

private:
    const Medium &medium_;
    std::vector<std::pair<double, double>> steps_;
};

}  // namespace

PhotonGatherer::PhotonGatherer(std::shared_ptr<const Scene> scene, int max_depth, uint64_t seed,
                               int spp_per_iteration, int threads)
    : scene_(std::move(scene)), depth_(max_depth), seed_(seed),
      spp_per_iteration_(std::max(1, spp_per_iteration)), threads_(std::max(1, threads)),
      film_(scene_->camera.width, scene_->camera.height) {
    paths_.resize(size_t(film_.width) * film_.height * spp_per_iteration_);
}

void PhotonGatherer::build_maps(const LightPathTracer &paths) {
    surface_photons_.clear();
    volume_photons_.clear();
    for (const LightVertex &v : paths.vertices()) {
        if (v.kind == VertexKind::Surface) surface_photons_.push_back(v);
        else if (v.kind == VertexKind::Medium) volume_photons_.push_back(v);
    }
    inv_light_paths_ = 1.0 / double(paths.paths_per_iteration());
    std::vector<Vec3> points(surface_photons_.size());
    for (size_t i = 0; i < points.size(); ++i) points[i] = surface_photons_[i].pos;
    surface_tree_.build(points, threads_);
    points.resize(volume_photons_.size());
    for (size_t i = 0; i < points.size(); ++i) points[i] = volume_photons_[i].pos;
    volume_tree_.build(points, threads_);
    stats_.surface_photons += surface_photons_.size();
    stats_.volume_photons += volume_photons_.size();
}

size_t PhotonGatherer::begin_camera(int64_t iteration, const RayBuffers &out) {
    const Camera &cam = scene_->camera;
    active_.clear();
    if (!depth_.allows(0)) return 0;  // Mitsuba: max_depth 0 renders black
    if (out.capacity < paths_.size()) throw std::invalid_argument("pm: ray buffers too small");
    return start_camera_wave(paths_, active_, cam, iteration, spp_per_iteration_, seed_ ^ stream_tag::kGatherPaths, out,
                             threads_);
}

// Beam radiance estimate along [0, t_hit] (Jarosz et al. 2008): every volume photon
// of this medium whose disc crosses the segment, attenuated to the camera-path vertex.
RGB PhotonGatherer::beam_estimate(const GatherPath &p, double t_hit, double radius, Sampler rng,
                                  MediumStats &ms, uint64_t &accepted) const {
    const Medium &m = scene_->media[p.medium];
    double tmax = std::isfinite(t_hit) ? t_hit + p.lead : 1e30;
    const Vec3 origin = segment_origin(p);
    TransmittanceTrack track(m, origin, p.dir, tmax, rng, ms);
    RGB sum(0.0);
    const double kernel = 1 / (kPi * radius * radius);
    Vec3 to_camera = -p.dir;
    volume_tree_.query_ray(origin, p.dir, tmax, radius, [&](uint32_t i, double t, double) {
        const LightVertex &ph = volume_photons_[i];
        if (ph.medium != p.medium) return;
        if (!depth_.allows(ph.depth + p.specular)) return;
        ++accepted;
        sum += track.at(t) * ph.power * phase_eval(m.phase, ph.wi, to_camera);
    });
    return sum * (kernel * inv_light_paths_);
}

// Surface density estimate at x (Jensen 1996) with a constant kernel 1 / (pi r^2).
RGB PhotonGatherer::surface_estimate(const GatherPath &p, int tri, const Vec3 &x, double radius,
                                     uint64_t &accepted) const {
    RGB reflected = reflected_photon_power(*scene_, surface_tree_, surface_photons_, tri, x, -p.dir, radius,
                                           [&](const LightVertex &ph) {
                                               if (!depth_.allows(ph.depth + p.specular)) return false;
                                               ++accepted;
                                               return true;
                                           });
    return reflected * (inv_light_paths_ / (kPi * radius * radius));
}

void PhotonGatherer::shade(const Hits &hits, double surface_radius, double volume_radius) {
    const Scene &scene = *scene_;
    hits.expect(active_.size(), "pm shade");
    // The kernels divide by pi r^2: a radius of 0, or one so small that 1 / (pi r^2) is
    // infinite, would make every estimate without a photon 0 * inf.
    auto usable = [](double r) { return r > 0 && std::isfinite(r) && std::isfinite(1 / (kPi * r * r)); };
    if (!(usable(surface_radius) && usable(volume_radius)))
        throw std::invalid_argument("pm shade: radii must be positive and finite, with 1 / (pi r^2) finite");
    uint64_t lookups = 0, surface_accepted = 0, volume_accepted = 0;
    const DepthLimit specular_limit = depth_.unlimited() ? DepthLimit(kMaxSpecularBounces) : depth_;
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads_) \
    reduction(+ : lookups, surface_accepted, volume_accepted)
    for (int64_t k = 0; k < int64_t(hits.count); ++k) {
        GatherPath &p = paths_[active_[k]];
        int tri = hits.prim[k];
        double t_hit = tri >= 0 ? double(hits.tfar[k]) : kInf;
        if (p.medium >= 0) {
            MediumStats local;
            const Medium &m = scene.media[p.medium];
            // Each medium segment gets fresh streams: segments split by null surfaces
            // would otherwise share their random numbers and correlate their estimates.
            p.radiance += p.throughput * beam_estimate(p, t_hit, volume_radius, p.rng.fork(), local,
                                                       volume_accepted);
            if (tri >= 0) {
                Sampler rng = p.rng.fork();
                p.throughput *= transmittance(m, segment_origin(p), p.dir, t_hit + p.lead, rng, local);
            }
            lookups += local.density_lookups;
        }
        if (tri < 0 || is_black(p.throughput)) {
            p.alive = false;
            continue;
        }
        const Triangle &T = scene.triangles[tri];
        const Material &mat = scene.materials[T.material];
        Vec3 x = T.point(hits.u[k], hits.v[k]);
        // Emitters seen directly or through specular chains: full weight (no NEE here).
        if (depth_.allows(p.specular)) p.radiance += p.throughput * scene.emitted(tri, p.dir);
        if (mat.type == MaterialType::Null) {
            cross_null_boundary(scene, p, tri, x);
            continue;
        }
        if (!mat.is_delta()) {
            p.radiance += p.throughput * surface_estimate(p, tri, x, surface_radius, surface_accepted);
            p.alive = false;
            continue;
        }
        // Specular: follow the chain (radiance transport, weights <= 1: no roulette).
        if (!specular_limit.allows(++p.specular)) {
            p.alive = false;
            continue;
        }
        advance_by_bsdf(scene, p, p.throughput, tri, x, /*radiance=*/true);
    }
    medium_stats_.density_lookups += lookups;
    stats_.surface_lookups += surface_accepted;
    stats_.volume_lookups += volume_accepted;
}

size_t PhotonGatherer::next_rays(const RayBuffers &out) {
    return write_alive_rays(active_, paths_, out, threads_);
}

void PhotonGatherer::end_iteration() {
    add_paths_to_film(film_, paths_, spp_per_iteration_);
    active_.clear();
}

}  // namespace pgi
