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
      volume_schedules_(std::max<size_t>(1, scene_->media.size()),
                        RadiusSchedule(usable_radius(volume_radius), volume_alpha, kDimension)),
      volume_radii_(volume_schedules_.size(), 0.0), film_(scene_->camera.width, scene_->camera.height) {
    paths_.resize(size_t(film_.width) * film_.height * spp_per_iteration_);
}

void PhotonMapping::set_surface_radius(double radius) {
    surface_schedule_ = RadiusSchedule(usable_radius(radius), surface_schedule_.alpha, kDimension);
}

void PhotonMapping::set_volume_radius(int medium, double radius) {
    if (medium < 0 || medium >= int(scene_->media.size())) throw std::out_of_range("pm: no such medium");
    volume_schedules_[size_t(medium)] = RadiusSchedule(usable_radius(radius), volume_schedules_[0].alpha, kDimension);
}

const RadiusSchedule &PhotonMapping::volume_schedule(int medium) const {
    if (medium < 0 || medium >= int(volume_schedules_.size())) throw std::out_of_range("pm: no such medium");
    return volume_schedules_[size_t(medium)];
}

void PhotonMapping::begin(int64_t iteration) {
    const LightPaths &paths = *light_paths_;
    if (paths.iteration() != iteration)
        throw std::logic_error("pm: the light paths of iteration " + std::to_string(iteration) + " come first");
    // The photons and their trees, once per iteration (the pilot's camera pass and the
    // iteration's own share them).
    if (photons_iteration_ != iteration) {
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
        photons_iteration_ = iteration;
    }
    active_.clear();
    if (pilot_.on()) {
        // The pilot: the photons each kernel could gather, and a regular sample of the paths.
        std::vector<BoundingBox> boxes(volume_schedules_.size() + 1);
        for (const PathVertex &v : surface_photons_) boxes[0].add(v.pos);
        for (const PathVertex &v : volume_photons_)
            if (v.medium >= 0 && size_t(v.medium) + 1 < boxes.size()) boxes[size_t(v.medium) + 1].add(v.pos);
        pilot_.begin(boxes);
        if (!depth_.allows(0)) return;
        start_camera_wave(paths_, active_, scene_->camera, iteration, spp_per_iteration_,
                          seed_ ^ stream_tag::kGatherPaths, threads_);
        pilot_.sample_paths(paths_, active_);
        return;
    }
    stats_.surface_photons += surface_photons_.size();
    stats_.volume_photons += volume_photons_.size();
    // The iteration's radii (checked again: the schedule shrinks them).
    surface_radius_ = usable_radius(surface_schedule_.radius(iteration));
    for (size_t m = 0; m < volume_schedules_.size(); ++m)
        volume_radii_[m] = usable_radius(volume_schedules_[m].radius(iteration));

    if (!depth_.allows(0)) return;  // Mitsuba: max_depth 0 renders black
    start_camera_wave(paths_, active_, scene_->camera, iteration, spp_per_iteration_,
                      seed_ ^ stream_tag::kGatherPaths, threads_);
}

// Beam radiance estimate along [0, t_hit] (Jarosz et al. 2008): every volume photon
// of this medium whose disc crosses the segment, attenuated to the camera-path vertex.
// Near the planes the segment starts and ends on, the discs lie parallel to them
// (boundary_kernels.h): a photon counts where the plane through it crosses the ray.
RGB PhotonMapping::beam_estimate(const GatherPath &p, double t_hit, const BoundaryPlane &exit, double radius,
                                  Sampler rng, MediumStats &ms, uint64_t &accepted) const {
    const Medium &m = scene_->media[p.medium];
    double tmax = std::isfinite(t_hit) ? t_hit + p.lead : 1e30;
    const Vec3 origin = segment_origin(p);
    TransmittanceTrack track(m, origin, p.dir, tmax, rng, ms);
    const KernelZones zones = kernel_zones(p.dir, tmax, radius, triangle_plane(*scene_, p.start_triangle, p.dir), exit);
    const double r2 = radius * radius;
    RGB sum(0.0);
    const double kernel = 1 / (kPi * radius * radius);
    Vec3 to_camera = -p.dir;
    // Photons that an aligned disc may reach lie up to r beyond its zone along the ray.
    const double lo = zones.lo(radius), hi = zones.hi(radius);
    const Vec3 query_origin = origin + p.dir * lo;
    // Sum of the weights (Tr at the photon's t, over |d.n|) of the discs that hold photon i.
    auto aligned = [&](const BoundaryPlane &plane, double t0, double t1, const Vec3 &pos) {
        double t = dot(pos - origin, plane.normal) / dot(p.dir, plane.normal);
        if (!(t >= t0 && t < t1)) return RGB(0.0);
        Vec3 e = pos - (origin + p.dir * t);
        if (!(dot(e, e) < r2)) return RGB(0.0);
        return track.at(t) / plane.cosine;
    };
    volume_tree_.query_ray(query_origin, p.dir, hi - lo, radius, [&](uint32_t i, double t, double d2) {
        const PathVertex &ph = volume_photons_[i];
        if (ph.medium != p.medium) return;
        if (!depth_.allows(ph.depth + p.specular)) return;
        t += lo;
        RGB w(0.0);
        bool before_exit = zones.exit_start < tmax ? t < zones.exit_start : t <= tmax;
        if (t >= zones.entry_end && before_exit && d2 < r2) w += track.at(t);
        if (zones.entry_end > 0) w += aligned(zones.entry, 0.0, zones.entry_end, ph.pos);
        if (zones.exit_start < tmax) w += aligned(zones.exit, zones.exit_start, tmax, ph.pos);
        if (is_black(w)) return;
        ++accepted;
        sum += w * ph.throughput * phase_eval(m.phase, ph.wi, to_camera);
    });
    return sum * (kernel * inv_light_paths_);
}

// Pilot: the distance within which the k nearest photons of its medium lie around the segment
// up to a free flight along it (pilot_flight); none where the flight crosses the segment.
double PhotonMapping::pilot_segment(const GatherPath &p, double t_hit, Sampler rng, double &free_path) const {
    if (pilot_.medium_neighbours() == 0) return RadiusPilot::kNoRecord;
    double tmax = std::isfinite(t_hit) ? t_hit + p.lead : 1e30;
    const Vec3 origin = segment_origin(p);
    const PilotFlight flight = pilot_flight(scene_->media[p.medium], origin, p.dir, tmax, rng, p.rng);
    if (!std::isfinite(flight.t)) return RadiusPilot::kNoRecord;
    free_path = flight.free_path;
    return volume_tree_.kth_nearest_to_segment(
        origin, p.dir, flight.t, pilot_.medium_neighbours(), pilot_.max_radius(p.medium), [&](uint32_t i) {
            const PathVertex &ph = volume_photons_[i];
            return ph.medium == p.medium && depth_.allows(ph.depth + p.specular);
        });
}

// Pilot: the distance within which the k nearest photons that x's estimate would take lie.
double PhotonMapping::pilot_surface(const GatherPath &p, int tri, const Vec3 &x) const {
    const size_t k = pilot_.surface_neighbours();
    if (k == 0) return RadiusPilot::kNoRecord;
    return kth_nearest_surface_photon(*scene_, surface_tree_, surface_photons_, tri, x, -p.dir, k,
                                      pilot_.max_radius(-1), RadiusPilot::kNoRecord,
                                      [&](const PathVertex &ph) { return depth_.allows(ph.depth + p.specular); });
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
    const bool pilot = pilot_.on();
    if (pilot) pilot_.open_hits(hits.count);
    const double surface_radius = surface_radius_;
    uint64_t lookups = 0, surface_accepted = 0, volume_accepted = 0;
    const DepthLimit specular_limit = depth_.unlimited() ? DepthLimit(kMaxSpecularBounces) : depth_;
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads_) \
    reduction(+ : lookups, surface_accepted, volume_accepted)
    for (int64_t k = 0; k < int64_t(hits.count); ++k) {
        GatherPath &p = paths_[active_[k]];
        int tri = hits.prim[k];
        double t_hit = tri >= 0 ? double(hits.tfar[k]) : kInf;
        if (p.medium >= 0 && pilot) {
            double free_path = RadiusPilot::kNoRecord;
            const double distance = pilot_segment(p, t_hit, p.rng.fork(), free_path);
            pilot_.record_segment(size_t(k), p.medium, distance, free_path);
        } else if (p.medium >= 0) {
            MediumStats local;
            const Medium &m = scene.media[p.medium];
            const BoundaryPlane exit = triangle_plane(scene, tri, p.dir);
            // Each medium segment gets fresh streams: segments split by null surfaces
            // would otherwise share their random numbers and correlate their estimates.
            p.radiance += p.throughput * beam_estimate(p, t_hit, exit, volume_radii_[size_t(p.medium)], p.rng.fork(),
                                                       local, volume_accepted);
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
            p.start_triangle = tri;
            continue;
        }
        if (!mat.is_delta()) {
            if (pilot) pilot_.record_surface(size_t(k), pilot_surface(p, tri, x));
            else p.radiance += p.throughput * surface_estimate(p, tri, x, surface_radius, surface_accepted);
            p.alive = false;
            continue;
        }
        // Specular: follow the chain (radiance transport, weights <= 1: no roulette).
        if (!specular_limit.allows(++p.specular)) {
            p.alive = false;
            continue;
        }
        advance_by_bsdf(scene, p, p.throughput, tri, x, /*radiance=*/true);
        p.start_triangle = tri;
    }
    if (pilot) pilot_.close_hits();
    medium_stats_.density_lookups += lookups;
    stats_.surface_lookups += surface_accepted;
    stats_.volume_lookups += volume_accepted;
    return 0;
}

size_t PhotonMapping::next_rays(const RayBuffers &out) {
    return write_alive_rays(active_, paths_, out, threads_);
}

void PhotonMapping::end() {
    active_.clear();
    if (pilot_.on()) return;  // a pilot estimates nothing
    add_paths_to_film(film_, paths_, spp_per_iteration_);
}

}  // namespace pgi
