// Camera paths: the state and the steps shared by every method that traces
// from the camera (pt's lanes, and the gathering paths of ppb; ppb and pm also
// use the whole-wave bookkeeping below: start_camera_wave).
// Each step is one piece of volumetric path tracing with NEE and MIS (Veach 1997, ch. 9), with Mitsuba volpath's conventions: depth
// counts real scattering events, null crossings are free, Russian roulette
// after rr_depth events on max(throughput) * eta^2.
#pragma once

#include <type_traits>
#include <vector>

#include "wavefront.h"

namespace pgi {

struct CameraPath {
    Vec3 pos, dir;
    double lead = 0;     // medium behind pos (start_path_at)
    RGB throughput{1.0};
    RGB radiance{0.0};   // everything this path has gathered so far
    Vec3 prev_pos;       // last real scattering vertex (for the light pdf in MIS)
    double prev_pdf = 0; // solid-angle pdf of the direction sampled there
    double eta2 = 1;     // product of squared IOR ratios crossed (for Russian roulette)
    int64_t pixel = 0;
    int depth = 0;       // real scattering events so far
    int medium = -1;
    int null_crossings = 0;
    bool prev_delta = true;
    bool alive = false;
    Sampler rng;
    SpectralMis spectral;  // hero channel and path pdf ratios in chromatic media
};

// Paths that sample free flights carry a SpectralMis (CameraPath's); pm's gathering paths,
// which take transmittance in closed form, do not.
template <typename Path, typename = void>
struct samples_free_flights : std::false_type {};
template <typename Path>
struct samples_free_flights<Path, std::void_t<decltype(std::declval<Path &>().spectral)>> : std::true_type {};

// Box-filtered camera sample through `pixel`: the path's first ray is (p.pos, p.dir).
template <typename Path>
void start_camera_path(Path &p, const Camera &cam, int64_t pixel, Sampler rng) {
    // Copied from a default path: value-initialising a temporary compiled to `rep stos`,
    // whose start-up cost made this the slowest line of the camera pass.
    static const Path fresh{};
    p = fresh;
    p.rng = rng;
    if constexpr (samples_free_flights<Path>::value) p.spectral.hero = hero_channel(rng);
    p.pixel = pixel;
    double fx = double(pixel % cam.width) + p.rng.next();
    double fy = double(pixel / cam.width) + p.rng.next();
    p.pos = cam.origin;
    p.dir = cam.direction(fx, fy);
    p.medium = cam.medium;
    p.alive = true;
}

// Starts path number `path` of wave `iteration`, a wave of spp samples per pixel: it samples
// pixel path % npix, with its random stream keyed by (stream_seed, sample index, pixel), so a
// pixel's samples do not depend on the wave size.
template <typename Path>
void start_camera_sample(Path &p, const Camera &cam, int64_t path, int64_t iteration, int spp, uint64_t stream_seed) {
    const int64_t npix = int64_t(cam.width) * cam.height;
    const int64_t pixel = path % npix, sample = iteration * spp + path / npix;
    start_camera_path(p, cam, pixel, Sampler(stream_key(stream_seed, uint64_t(sample), uint64_t(pixel))));
}

// Starts a whole wave of spp camera paths per pixel (start_camera_sample) and lists them all
// in `active`, in path order; their first rays are written by write_alive_rays.
template <typename Path>
void start_camera_wave(std::vector<Path> &paths, std::vector<int32_t> &active, const Camera &cam,
                       int64_t iteration, int spp, uint64_t stream_seed, int threads) {
    active.resize(paths.size());
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int64_t i = 0; i < int64_t(paths.size()); ++i) {
        start_camera_sample(paths[i], cam, i, iteration, spp, stream_seed);
        active[i] = int32_t(i);
    }
}

class CameraPathSteps {
public:
    CameraPathSteps(const Scene &scene, int max_depth, int rr_depth)
        : scene_(scene), depth_(max_depth), rr_depth_(rr_depth) {}

    // Emission found by the sampled direction, weighted against light sampling.
    void add_emission(CameraPath &p, int tri, const Vec3 &x) const {
        RGB Le = scene_.emitted(tri, p.dir);
        if (is_black(Le)) return;
        double w = p.prev_delta ? 1.0 : power_heuristic(p.prev_pdf, scene_.area_light_pdf(tri, p.prev_pos, x));
        p.radiance += p.throughput * Le * w;
    }
    // The path's ray ended on triangle `tri` at barycentrics (u, v), or escaped (tri < 0):
    // emission found there is added and null boundaries are crossed. True when x is a
    // scattering surface the method handles next.
    bool reach_surface(CameraPath &p, int tri, double u, double v, Vec3 &x) const {
        if (tri < 0) {  // escaped: the scenes have no environment light
            p.alive = false;
            return false;
        }
        x = scene_.triangles[tri].point(u, v);
        add_emission(p, tri, x);
        if (scene_.materials[scene_.triangles[tri].material].type == MaterialType::Null) {
            cross_null_boundary(scene_, p, tri, x);
            return false;
        }
        return true;
    }
    // Counts a real scattering event; false (and the path ends) when no path through it is
    // within max_depth (NEE from here already makes a path of p.depth events).
    bool count_event(CameraPath &p) const {
        if (!depth_.allows(++p.depth)) p.alive = false;
        return p.alive;
    }
    // A shadow ray towards a light sample, weighted by the power heuristic
    // against the BSDF/phase pdf (1 for delta lights). `receiver` gets it.
    void next_event(const CameraPath &p, ShadowRay &r, int64_t receiver, const LightSample &ls, const RGB &f,
                    double pdf_dir, const RayStart &origin, int medium) const {
        r.live = false;
        if (!ls.valid || is_black(f)) return;
        double w = ls.delta ? 1.0 : power_heuristic(ls.pdf, pdf_dir);
        r.dir = ls.wi;
        r.to_infinity = !std::isfinite(ls.dist);
        r.target = r.to_infinity ? Vec3() : ls.point;
        r.target_eps = r.to_infinity ? 0 : scene_.light_clearance(ls.point);
        r.restart_at(origin);
        r.medium = medium;
        r.contribution = p.throughput * f * ls.value * w;
        r.rng = p.rng.split(uint64_t(p.depth));
        r.receiver = receiver;
        r.live = !is_black(r.contribution);
    }
    // Free flight through the path's medium towards the surface at t_hit: the throughput
    // takes the flight's weight, and a real collision before the surface scatters the path
    // there (scatter_in_medium). True when it did.
    bool fly_through_medium(CameraPath &p, ShadowRay &r, int64_t receiver, double t_hit, MediumStats &stats) const {
        FreeFlight ff = sample_free_flight(scene_.media[p.medium], segment_origin(p), p.dir, t_hit + p.lead, p.rng,
                                           stats, p.spectral);
        p.throughput *= ff.weight;
        if (!ff.scattered) return false;
        scatter_in_medium(p, r, receiver, segment_point(p, ff.t));
        return true;
    }
    // Real collision at x: NEE by the phase function, then a phase-sampled direction.
    void scatter_in_medium(CameraPath &p, ShadowRay &r, int64_t receiver, const Vec3 &x) const {
        r.live = false;
        if (!count_event(p)) return;
        const Medium &m = scene_.media[p.medium];
        Vec3 wo = -p.dir;
        LightSample ls = scene_.sample_light(x, p.rng);
        if (ls.valid) {
            double f = phase_eval(m.phase, wo, ls.wi);
            next_event(p, r, receiver, ls, RGB(f), f, RayStart{x}, p.medium);
        }
        p.prev_pdf = advance_by_phase(m, p, x);
        p.prev_pos = x;
        p.prev_delta = false;
        p.alive = russian_roulette(p);
    }
    // NEE at a non-delta surface vertex (the event at x already counted). Without `mis` the
    // light sample takes full weight: for a path that ends here, no BSDF-sampled emission
    // competes with it.
    void next_event_on_surface(CameraPath &p, ShadowRay &r, int64_t receiver, int tri, const Vec3 &x,
                               bool mis = true) const {
        const Triangle &T = scene_.triangles[tri];
        const Material &mat = scene_.materials[T.material];
        LightSample ls = scene_.sample_light(x, p.rng);
        if (!ls.valid) return;
        Vec3 wo = -p.dir;
        if (!mis) ls.delta = true;  // power heuristic weight 1
        next_event(p, r, receiver, ls, bsdf_eval(mat, T.n, wo, ls.wi), bsdf_pdf(mat, T.n, wo, ls.wi),
                   scene_.spawn(x, tri, ls.wi), T.medium_after(p.medium, ls.wi));
    }
    // Continues by BSDF sampling at surface vertex x (the event already counted), with
    // radiance transport; the MIS state and eta^2 are what a camera path adds.
    void continue_by_bsdf(CameraPath &p, int tri, const Vec3 &x) const {
        const BsdfSample bs = advance_by_bsdf(scene_, p, p.throughput, tri, x, /*radiance=*/true);
        if (!bs.valid) return;
        p.prev_pos = x;
        p.prev_pdf = bs.pdf;
        p.prev_delta = bs.delta;
        p.eta2 *= bs.eta * bs.eta;
        p.alive = russian_roulette(p);
    }
    // A path that carries nothing ends (it could add nothing more, and would trace rays until
    // rr_depth); after rr_depth real events, survive_roulette on max(throughput) * eta^2 (the
    // eta^2 undoes refraction's scaling of radiance, as in Mitsuba and pbrt).
    bool russian_roulette(CameraPath &p) const {
        if (is_black(p.throughput)) return false;
        if (p.depth <= rr_depth_) return true;
        return survive_roulette(p.throughput, max_component(p.throughput) * p.eta2, p.rng, scene_.roulette);
    }

private:
    const Scene &scene_;
    DepthLimit depth_;
    int rr_depth_;
};

// Adds each path's radiance to its pixel, in path order (deterministic).
template <typename Path>
void add_paths_to_film(Film &film, const std::vector<Path> &paths, int spp) {
    for (const Path &p : paths) film.add(p.pixel, p.radiance);
    film.samples_per_pixel += spp;
}

}  // namespace pgi
