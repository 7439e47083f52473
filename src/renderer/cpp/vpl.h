// vpl: virtual point lights (instant radiosity) in participating media, with clamping; and the
// gathering kernel it shares with vsl (vsl.h), which spreads each light over a sphere instead.
//   Keller 1997, "Instant radiosity" (SIGGRAPH); Keller & Heidrich 2001, "Interleaved sampling"
//     (EGWR): the lights shared out among a pixel's samples;
//   Kulla & Fajardo 2012, "Importance sampling techniques for path tracing in participating
//     media" (EGSR): equi-angular sampling along camera rays (equiangular.h);
//   Kollig & Keller 2004, "Illumination in the presence of weak singularities" and Walter et
//     al. 2005 ("Lightcuts") for clamping the geometry term; a progressive bound as in the
//     progressive variants of many-light methods.
//
// One iteration (methods/vpl.py runs the passes):
//   1. LightPaths (subpaths.h): N = light_paths paths; their vertices become this iteration's
//      virtual lights y_j with power Phi_j (virtual_lights.h: area lights' own points,
//      non-delta surface vertices, medium collisions, each with power beta_j / N; point, spot
//      and directional lights one each, exact);
//   2. this kernel: S = spp_per_iteration camera paths per pixel walk from the camera
//      (GatherWalk in virtual_lights.h: specular chains followed, emission they reach added) and
//      make gather jobs; each job gathers its lights through shadow rays (ConnectionStream), and
//      the values go to the job's path, then its pixel. Which lights: every one, or (shared
//      lights, the default) the exact lights and the s-th of every S others for sample s of its
//      pixel, weighted S: each pixel still gathers every light once per iteration, at the cost
//      of one sample per light, while its S samples spread over the pixel (interleaved
//      sampling, Keller & Heidrich 2001, within a pixel). Unbiased: a sample's camera path does
//      not depend on which share it gathers.
//
// The estimator of one iteration, for a camera path of throughput beta (the sums run over the
// job's lights, with Phi_j times S for shared ones):
//   at a surface job x:
//     L = beta sum_j Phi_j F_x(w_j) F_j(-w_j) V(x, y_j) T(x, y_j) / max(|x - y_j|^2, d_i^2)
//   along a medium segment x(t) = o + t d, t in [0, l), beta at o: for each light one point t_j
//   drawn equi-angularly about y_j (probability 1 - c) or by the segment's free-flight density
//   (probability c, `free_flight_fraction`: the truncated exponential of the medium's mean
//   extinction, uniform over a density grid's box), one-sample MIS with the balance heuristic:
//     L = beta sum_j T(o, x_j) sigma_s(x_j) Phi_j F_x F_j V T(x_j, y_j) / max(|x_j - y_j|^2, d_i^2)
//             / p(t_j),   p = (1 - c) p_equiangular + c p_free
//   with x_j = x(t_j); for c = 0 the factor 1 / (|x_j - y_j|^2 p) is (theta_1 - theta_0) / h
//   (equiangular.h) times min(1, |x_j - y_j|^2 / d_i^2). T(o, x_j) is the closed form in
//   homogeneous media and one ratio-tracking walk per segment in grids; T(x_j, y_j) that of the
//   shadow ray (the scene's estimator). w_j is the unit direction from x to y_j; F_x and F_j as
//   in virtual_lights.h. A directional light has no G: L = beta E F_x(-w_sun) V T, and along a
//   segment its point comes from the free-flight density alone.
//   A light of depth k joined to a job of s camera-side events (the gather point's included)
//   makes a path of k + s real events: it is gathered iff DepthLimit::allows(k + s).
//
// Clamping (on the geometry term's distance): 1 / |x - y|^2 becomes 1 / max(|x - y|^2, d_i^2),
// so a contribution can only shrink: a clamped image is darker, never brighter, than the
// unclamped one with the same random numbers, and more so for a larger d_i. Exact lights (point,
// spot, directional: the scene's own delta lights) are never clamped. The bound d_i:
//   none         d_i = 0: unbiased for the paths it covers (BDPT's unweighted t = 2 strategies
//                with shared light paths), with infinite variance where a medium light meets a
//                surface point or a camera ray nearby (1 / d^4 over a volume diverges);
//   fixed        d_i = d_1: bias that never vanishes, finite variance;
//   progressive  d_i = d_1 i^(alpha - 1) (i = 1, 2, ...; radius_schedule.h with d = 1): the bound
//                on G, 1 / d_i^2 = i^(2 (1 - alpha)) / d_1^2, relaxes each iteration. The clamp's
//                bias is of order d_i (the light within d_i of a gather point, ~ d^2 dd / d^2 over
//                a volume) and its variance grows as 1 / d_i (1 / d^4 over a volume beyond d_i),
//                so the running mean's MSE falls as n^-min(alpha, 2 (1 - alpha)): n^-2/3 at the
//                default alpha = 2/3, and the bias vanishes as iterations grow.
// Pairs closer than 1e-9 scene radii are skipped (a coincident point and light: a set of measure
// zero whose 1 / d^2 would overflow); so are lights on a camera ray's line (h = 0).
//
// Coverage (docs/methods.md): every path camera -> ... -> light, once (GatherWalk): joins of a
// gather point to a light-path vertex, emission at the end of specular chains from the camera,
// and, in scenes with specular surfaces, camera paths that go on from a gather point to find
// paths whose next vertex is specular (caustics, single scattering lit through glass), path
// traced.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "equiangular.h"
#include "passes.h"
#include "radius_schedule.h"
#include "virtual_lights.h"

namespace pgi {

// Shadow-ray pairs per chunk of the connection stream: about 6 MB of rays in flight (chunks of
// 2^14 to 2^16 pairs were fastest on cbox and cbox-fog; 2^12 and 2^17 up to 40 % slower).
constexpr size_t kVirtualLightChunk = size_t(1) << 15;

// Joins closer than this fraction of the scene's radius are skipped (see above).
constexpr double kCoincidentFraction = 1e-9;

// vpl's transfer from a virtual light to a gather point: F_x F_y / max(d^2, d_i^2), clamped by
// the iteration's bound d_i (above).
class PointTransfer {
public:
    enum class Clamp : int { None = 0, Fixed = 1, Progressive = 2 };

    void set_clamp(Clamp mode, double distance, double alpha) {
        mode_ = mode;
        if (mode == Clamp::None) return;
        schedule_ = RadiusSchedule(distance, mode == Clamp::Fixed ? 1.0 : alpha, 1);
    }
    Clamp clamp() const { return mode_; }
    // d_i of iteration i (0-based), 0 without clamping.
    double distance(int64_t iteration) const { return mode_ == Clamp::None ? 0.0 : schedule_.radius(iteration); }
    const RadiusSchedule &schedule() const { return schedule_; }
    void begin(int64_t iteration) {
        const double d = distance(iteration);
        distance2_ = d * d;
    }
    // F_x(w) F_y(-w) over max(d^2, d_i^2), or (times_d2) times d^2.
    RGB operator()(const Scene &scene, const GatherPoint &x, const VirtualLight &y, const Vec3 &w, double d2,
                   bool times_d2, const Sampler &) const {
        const RGB f = gather_scattering(scene, x, w) * virtual_light_emission(scene, y, -w);
        if (times_d2) return d2 < distance2_ ? f * (d2 / distance2_) : f;
        return f / std::max(d2, distance2_);
    }

private:
    Clamp mode_ = Clamp::None;
    RadiusSchedule schedule_;
    double distance2_ = 0;
};

// The counts of one run (all iterations).
struct VirtualLightStats {
    uint64_t lights = 0;  // virtual lights gathered
    uint64_t jobs = 0;    // gather jobs (surface points and medium segments)
    uint64_t pairs = 0;   // job x light pairs
};

// Lights a gathering kernel joins beyond the virtual point lights: none for vpl and vsl; vrl and
// vbl's ray lights (ray_lights.h), which replace the medium vertices' point lights. `begin` may
// drop lights from the list (the exact ones stay first); `aim` is the kernel's aim for extra
// light `index` (ExtraLightJob: what the kernel knows of the job).
struct ExtraLightJob {
    const GatherJob &job;
    const TransmittanceTrack *track;  // a segment job's in a grid
    double share;                     // the light's weight for sharing (S, or 1)
    double min_distance2;             // joins closer than this are skipped
    const DepthLimit &depth;
};
struct NoExtraLights {
    void begin(const Scene &, const LightPaths &, std::vector<VirtualLight> &, int64_t) {}
    int64_t size() const { return 0; }
    void aim(const Scene &, const ExtraLightJob &, int64_t, Sampler &, ShadowRay &, MediumStats &) const {}
};

// The gathering kernel of vpl (Transfer = PointTransfer) and vsl (SphereTransfer, vsl.h), and with
// Extra lights of vrl and vbl (ray_lights.h).
template <typename Transfer, typename Extra = NoExtraLights>
class VirtualLightGathering : public SingleLane<VirtualLightGathering<Transfer, Extra>> {
public:
    VirtualLightGathering(std::shared_ptr<const Scene> scene, std::shared_ptr<const LightPaths> light_paths,
                          int max_depth, int rr_depth, uint64_t seed, int spp_per_iteration, int threads)
        : scene_(std::move(scene)), light_paths_(std::move(light_paths)), depth_(max_depth), seed_(seed),
          spp_(std::max(1, spp_per_iteration)), threads_(std::max(1, threads)),
          walk_(*scene_, max_depth, rr_depth, has_specular_surfaces(*scene_)), stream_(kVirtualLightChunk),
          film_(scene_->camera.width, scene_->camera.height) {
        paths_.resize(size_t(film_.width) * film_.height * spp_);
        min_distance2_ = kCoincidentFraction * scene_->scene_radius;
        min_distance2_ *= min_distance2_;
    }

    Transfer &transfer() { return transfer_; }
    const Transfer &transfer() const { return transfer_; }
    Extra &extra() { return extra_; }
    const Extra &extra() const { return extra_; }
    // c: the probability of drawing a segment's point by its free-flight density (above).
    void set_free_flight_fraction(double c) {
        if (!(c >= 0 && c <= 1)) throw std::invalid_argument("free_flight_fraction must lie in [0, 1]");
        free_flight_fraction_ = c;
    }
    bool continuations() const { return walk_.continuations(); }
    // Each of a pixel's spp_per_iteration samples gathers its share of the light-path vertices'
    // lights (above); every sample gathers the exact lights.
    void set_share_lights(bool on) { share_lights_ = on; }
    bool share_lights() const { return share_lights_; }
    // Lights each gather job joins: the exact ones, then all the others or its sample's share
    // (the last shares may be one short).
    int64_t lights_per_job() const {
        const int64_t shared = int64_t(lights_.size()) - exact_lights_ + extra_.size();
        return exact_lights_ + (share_lights_ ? (shared + spp_ - 1) / spp_ : shared);
    }
    // Shadow-ray pairs per chunk of the connection stream (speed and memory only).
    void set_chunk_pairs(size_t pairs) { stream_.set_chunk(pairs); }

    size_t capacity() const { return paths_.size(); }
    size_t shadow_slots() const { return stream_.slots(); }

    // Pass 1: this iteration's virtual lights (its light paths were traced first), its clamp or
    // radius, its camera paths.
    void begin(int64_t iteration) {
        if (light_paths_->iteration() != iteration)
            throw std::logic_error("virtual lights: the light paths of iteration " + std::to_string(iteration) +
                                   " come first");
        lights_ = collect_virtual_lights(*scene_, *light_paths_);
        extra_.begin(*scene_, *light_paths_, lights_, iteration);
        exact_lights_ = 0;
        while (exact_lights_ < int64_t(lights_.size()) && lights_[size_t(exact_lights_)].exact()) ++exact_lights_;
        transfer_.begin(iteration);
        stats_.lights += lights_.size() + uint64_t(extra_.size());
        jobs_.clear();
        tracks_.clear();
        stream_.start(0, 1);
        active_.clear();
        if (!depth_.allows(0)) return;  // Mitsuba: max_depth 0 renders black
        start_camera_wave(paths_, active_, scene_->camera, iteration, spp_,
                          seed_ ^ stream_tag::kVirtualLightGather, threads_);
    }
    size_t next_rays(const RayBuffers &out) { return write_alive_rays(active_, paths_, out, threads_); }
    // Pass 2: each traced ray moves its path on (GatherWalk) and makes its jobs; returns the
    // pairs of jobs and lights to join (their shadow rays come from shadow_rays).
    size_t shade(const Hits &hits) {
        hits.expect(active_.size(), "virtual lights shade");
        slot_jobs_.resize(hits.count);
        MediumStats local;
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads_) reduction(+ : local)
        for (int64_t k = 0; k < int64_t(hits.count); ++k) {
            const int32_t index = active_[size_t(k)];
            const int tri = hits.prim[k];
            walk_.step(paths_[size_t(index)], index, tri, tri >= 0 ? double(hits.tfar[k]) : kInf, hits.u[k],
                       hits.v[k], local, slot_jobs_[size_t(k)]);
        }
        medium_stats_ += local;
        jobs_.clear();
        tracks_.clear();
        for (GatherWalk::Jobs &j : slot_jobs_) {
            if (j.has_segment) {
                if (scene_->media[size_t(j.segment.at.medium)].type == MediumType::Grid) {
                    j.segment.track = int32_t(tracks_.size());
                    tracks_.push_back(std::move(j.track));
                }
                jobs_.push_back(j.segment);
            }
            if (j.has_surface) jobs_.push_back(j.surface);
        }
        stats_.jobs += jobs_.size();
        stream_.start(int64_t(jobs_.size()), lights_per_job());
        stats_.pairs += uint64_t(stream_.pairs());
        return size_t(stream_.pairs());
    }
    size_t shadow_rays(const RayBuffers &out) {
        return stream_.write(
            out, threads_, medium_stats_,
            [&](int64_t job, int64_t k, ShadowRay &r, MediumStats &ms) { aim(job, k, r, ms); },
            [&](int64_t job, const RGB &value) { paths_[size_t(jobs_[size_t(job)].path)].radiance += value; });
    }
    void resolve_shadows(const Hits &hits) { stream_.resolve(*scene_, hits, threads_, medium_stats_); }
    // Last pass: each path's radiance to its pixel, in path order.
    void end() {
        add_paths_to_film(film_, paths_, spp_);
        active_.clear();
        jobs_.clear();
        tracks_.clear();
    }

    const Film &film() const { return film_; }
    const Scene &scene() const { return *scene_; }
    uint64_t density_lookups() const { return medium_stats_.density_lookups; }
    const VirtualLightStats &stats() const { return stats_; }
    uint64_t shadow_rays_aimed() const { return stream_.rays_aimed(); }

    // The value the k-th light of a job brings it, before visibility and the shadow ray's
    // transmittance, and how its shadow ray goes (ray.live: whether there is one).
    void aim(int64_t job, int64_t k, ShadowRay &r, MediumStats &ms) const;

private:
    // Whether the light's centre lies on the lit side of both ends (surfaces are one-sided).
    bool faces(const GatherPoint &x, const VirtualLight &y, const Vec3 &w) const {
        if (x.on_surface() && dot(scene_->triangles[size_t(x.triangle)].n, w) <= 0) return false;
        switch (y.kind) {
            case VirtualLightKind::Surface: return dot(scene_->triangles[size_t(y.triangle)].n, w) < 0;
            case VirtualLightKind::AreaLight: return dot(y.axis, w) < 0;
            default: return true;
        }
    }

    std::shared_ptr<const Scene> scene_;
    std::shared_ptr<const LightPaths> light_paths_;
    DepthLimit depth_;
    uint64_t seed_;
    int spp_, threads_;
    GatherWalk walk_;
    Transfer transfer_;
    Extra extra_;
    double free_flight_fraction_ = 0;
    bool share_lights_ = true;
    int64_t exact_lights_ = 0;  // the first lights_ are the exact ones
    double min_distance2_ = 0;
    std::vector<VirtualLight> lights_;
    std::vector<GatherCameraPath> paths_;
    std::vector<int32_t> active_;
    std::vector<GatherWalk::Jobs> slot_jobs_;
    std::vector<GatherJob> jobs_;
    std::vector<TransmittanceTrack> tracks_;
    ConnectionStream stream_;
    Film film_;
    VirtualLightStats stats_;
    MediumStats medium_stats_;
};

template <typename Transfer, typename Extra>
void VirtualLightGathering<Transfer, Extra>::aim(int64_t job, int64_t k, ShadowRay &r, MediumStats &ms) const {
    const Scene &scene = *scene_;
    const GatherJob &J = jobs_[size_t(job)];
    r.live = false;
    // Shared lights: sample s of a pixel gathers the exact lights, then the others' s-th,
    // (s + S)-th, (s + 2 S)-th, ..., each S times over.
    const int64_t pixels = int64_t(film_.width) * film_.height;
    const bool shared = share_lights_ && k >= exact_lights_;
    const int64_t light = shared ? exact_lights_ + J.path / pixels + (k - exact_lights_) * spp_ : k;
    if (light >= int64_t(lights_.size()) + extra_.size()) return;
    const double share = shared ? double(spp_) : 1.0;
    Sampler rng = J.rng.split(uint64_t(light));
    if (light >= int64_t(lights_.size())) {
        const ExtraLightJob context{J, J.track >= 0 ? &tracks_[size_t(J.track)] : nullptr, share, min_distance2_,
                                    depth_};
        extra_.aim(scene, context, light - int64_t(lights_.size()), rng, r, ms);
        return;
    }
    const VirtualLight &Y = lights_[size_t(light)];
    if (!depth_.allows(Y.depth + J.events)) return;
    GatherPoint at = J.at;
    Vec3 w;
    RGB value;
    const bool directional = Y.kind == VirtualLightKind::Directional;
    if (!J.segment()) {
        if (directional) {
            w = -Y.axis;
            value = J.weight * Y.power * share * gather_scattering(scene, at, w);
        } else {
            const Vec3 d = Y.pos - at.pos;
            const double d2 = dot(d, d);
            if (!(d2 > min_distance2_)) return;
            w = d / std::sqrt(d2);
            if (!faces(at, Y, w)) return;
            const RGB transfer = Y.exact()
                                     ? gather_scattering(scene, at, w) * virtual_light_emission(scene, Y, -w) / d2
                                     : transfer_(scene, at, Y, w, d2, /*times_d2=*/false, rng);
            value = J.weight * Y.power * share * transfer;
        }
    } else {
        // A point of the segment for this light: equi-angular about it, or by the free-flight
        // density (one-sample MIS, balance heuristic).
        const Medium &m = scene.media[size_t(at.medium)];
        const Vec3 o = at.pos, dir = J.dir();
        const bool homogeneous = m.type == MediumType::Homogeneous;
        // The free-flight density, where it is drawn from (its grid span costs a traversal).
        const bool want_flight = directional || free_flight_fraction_ > 0;
        const TruncatedExponential flight =
            want_flight && homogeneous ? truncated_exponential(mean(m.sigma_t), J.length) : TruncatedExponential();
        double span0 = 0, span1 = J.length;
        const bool has_flight = want_flight && (homogeneous ? flight.valid
                                                            : grid_span(m, o, dir, J.length, span0, span1) &&
                                                                  std::isfinite(span1));
        auto flight_sample = [&](double u) {
            return homogeneous ? truncated_exponential_sample(flight, u) : span0 + u * (span1 - span0);
        };
        auto flight_pdf = [&](double t) {
            if (homogeneous) return truncated_exponential_pdf(flight, t);
            return t >= span0 && t <= span1 ? 1 / (span1 - span0) : 0.0;
        };
        double u = rng.next(), t;
        RGB per_unit;  // everything but T(o, x) sigma_s(x), over the point's density
        if (directional) {
            if (!has_flight) return;
            t = flight_sample(u);
            const double pdf = flight_pdf(t);
            if (!(pdf > 0)) return;
            w = -Y.axis;
            at.pos = o + dir * t;
            per_unit = gather_scattering(scene, at, w) / pdf;
        } else {
            const EquiAngular ea = equiangular(o, dir, 0.0, J.length, Y.pos);
            if (!ea.valid) return;
            const double c = has_flight ? free_flight_fraction_ : 0.0;
            if (u < c) {
                t = flight_sample(u / c);
            } else {
                t = equiangular_sample(ea, c > 0 ? (u - c) / (1 - c) : u);
            }
            at.pos = o + dir * t;
            const Vec3 d = Y.pos - at.pos;
            const double d2 = dot(d, d);
            if (!(d2 > min_distance2_)) return;
            w = d / std::sqrt(d2);
            if (!faces(at, Y, w)) return;
            // d^2 p(t), for the transfer times d^2: equi-angular's is h / (theta_1 - theta_0).
            const double pdf_d2 = (1 - c) * equiangular_pdf_times_distance2(ea) + (c > 0 ? c * flight_pdf(t) * d2 : 0.0);
            const RGB transfer_d2 = Y.exact() ? gather_scattering(scene, at, w) * virtual_light_emission(scene, Y, -w)
                                              : transfer_(scene, at, Y, w, d2, /*times_d2=*/true, rng);
            per_unit = transfer_d2 / pdf_d2;
        }
        if (is_black(per_unit)) return;
        const RGB camera = homogeneous ? beer_lambert(m.sigma_t, t) : tracks_[size_t(J.track)].at(t);
        value = J.weight * camera * scattering_coefficient(m, at.pos, ms) * Y.power * share * per_unit;
    }
    if (is_black(value)) return;
    aim_at_virtual_light(scene, r, at, Y, w);
    r.contribution = value;
    r.rng = rng.fork();
    r.live = true;
}

using VirtualPointLights = VirtualLightGathering<PointTransfer>;

}  // namespace pgi
