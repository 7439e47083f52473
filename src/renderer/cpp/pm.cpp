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

// The kernels divide by pi r^2: a radius of 0, or one so small that 1 / (pi r^2) is infinite,
// would make every estimate without a photon 0 * inf.
static double usable_radius(double r) {
    if (!(r > 0 && std::isfinite(r) && std::isfinite(1 / (kPi * r * r))))
        throw std::invalid_argument("pm: radii must be positive and finite, with 1 / (pi r^2) finite");
    return r;
}

PhotonMapping::PhotonMapping(std::shared_ptr<const Scene> scene, std::shared_ptr<const LightPaths> light_paths,
                             int max_depth, uint64_t seed, int spp_per_iteration, int threads, double surface_radius,
                             double surface_alpha, double volume_radius, double volume_alpha)
    : scene_(std::move(scene)), light_paths_(std::move(light_paths)), depth_(max_depth), seed_(seed),
      spp_per_iteration_(std::max(1, spp_per_iteration)), threads_(std::max(1, threads)),
      surface_schedule_(usable_radius(surface_radius), surface_alpha, kDimension),
      volume_schedule_(usable_radius(volume_radius), volume_alpha, kDimension),
      film_(scene_->camera.width, scene_->camera.height) {
    paths_.resize(size_t(film_.width) * film_.height * spp_per_iteration_);
}

void PhotonMapping::begin(int64_t iteration) {
    const LightPaths &paths = *light_paths_;
    if (paths.iteration() != iteration)
        throw std::logic_error("pm: the light paths of iteration " + std::to_string(iteration) + " come first");
    surface_photons_.clear();
    volume_photons_.clear();
    for (const PathVertex &v : paths.vertices()) {
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
    // The iteration's radii (checked again: the schedule shrinks them).
    surface_radius_ = usable_radius(surface_schedule_.radius(iteration));
    volume_radius_ = usable_radius(volume_schedule_.radius(iteration));

    active_.clear();
    if (!depth_.allows(0)) return;  // Mitsuba: max_depth 0 renders black
    start_camera_wave(paths_, active_, scene_->camera, iteration, spp_per_iteration_,
                      seed_ ^ stream_tag::kGatherPaths, threads_);
}

// Beam radiance estimate along [0, t_hit] (Jarosz et al. 2008): every volume photon
// of this medium whose disc crosses the segment, attenuated to the camera-path vertex.
RGB PhotonMapping::beam_estimate(const GatherPath &p, double t_hit, double radius, Sampler rng,
                                  MediumStats &ms, uint64_t &accepted) const {
    const Medium &m = scene_->media[p.medium];
    double tmax = std::isfinite(t_hit) ? t_hit + p.lead : 1e30;
    const Vec3 origin = segment_origin(p);
    TransmittanceTrack track(m, origin, p.dir, tmax, rng, ms);
    RGB sum(0.0);
    const double kernel = 1 / (kPi * radius * radius);
    Vec3 to_camera = -p.dir;
    volume_tree_.query_ray(origin, p.dir, tmax, radius, [&](uint32_t i, double t, double) {
        const PathVertex &ph = volume_photons_[i];
        if (ph.medium != p.medium) return;
        if (!depth_.allows(ph.depth + p.specular)) return;
        ++accepted;
        sum += track.at(t) * ph.throughput * phase_eval(m.phase, ph.wi, to_camera);
    });
    return sum * (kernel * inv_light_paths_);
}

// Surface density estimate at x (Jensen 1996) with a constant kernel 1 / (pi r^2).
RGB PhotonMapping::surface_estimate(const GatherPath &p, int tri, const Vec3 &x, double radius,
                                     uint64_t &accepted) const {
    RGB reflected = reflected_photon_power(*scene_, surface_tree_, surface_photons_, tri, x, -p.dir, radius,
                                           [&](const PathVertex &ph) {
                                               if (!depth_.allows(ph.depth + p.specular)) return false;
                                               ++accepted;
                                               return true;
                                           });
    return reflected * (inv_light_paths_ / (kPi * radius * radius));
}

size_t PhotonMapping::shade(const Hits &hits) {
    const Scene &scene = *scene_;
    hits.expect(active_.size(), "pm shade");
    const double surface_radius = surface_radius_, volume_radius = volume_radius_;
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
    return 0;
}

size_t PhotonMapping::next_rays(const RayBuffers &out) {
    return write_alive_rays(active_, paths_, out, threads_);
}

void PhotonMapping::end() {
    add_paths_to_film(film_, paths_, spp_per_iteration_);
    active_.clear();
}

}  // namespace pgi
