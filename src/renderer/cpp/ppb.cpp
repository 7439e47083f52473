#include "ppb.h"

#include <climits>

namespace pgi {

// Null crossings allowed per camera path before we call it trapped (as pt).
constexpr int kMaxNullCrossingsPpb = 256;

PhotonBeams::PhotonBeams(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed,
                         int spp_per_iteration, int threads, size_t max_beams, double radius, double alpha,
                         int gather_diffuse_bounces)
    : scene_(std::move(scene)), max_depth_(max_depth), rr_depth_(rr_depth), seed_(seed),
      spp_per_iteration_(std::max(1, spp_per_iteration)), threads_(std::max(1, threads)),
      gather_diffuse_bounces_(gather_diffuse_bounces),
      film_(scene_->camera.width, scene_->camera.height), bvh_(max_beams), schedule_(radius, alpha, 1) {
    paths_.resize(size_t(film_.width) * film_.height * spp_per_iteration_);
}

void PhotonBeams::set_surface_photons(double radius, double alpha) {
    surface_photons_ = radius > 0;
    if (surface_photons_) surface_schedule_ = RadiusSchedule(radius, alpha, 2);
}

void PhotonBeams::build_beams(const LightPathTracer &light, int64_t iteration, double max_piece_length) {
    if (surface_photons_) {
        // Direct light is next-event estimated: keep photons with depth >= 2.
        photons_.clear();
        std::vector<Vec3> points;
        for (const LightVertex &v : light.vertices())
            if (v.kind == VertexKind::Surface && v.depth >= 2) {
                photons_.push_back(v);
                points.push_back(v.pos);
            }
        photon_tree_.build(points);
        photon_radius_ = surface_schedule_.radius(iteration);
        photon_scale_ = 1.0 / (kPi * photon_radius_ * photon_radius_ * double(light.paths_per_iteration()));
        stats_.photons += photons_.size();
    }
    double radius = schedule_.radius(iteration);
    // Short beams: each recorded medium segment up to its sampled collision (or
    // the surface when none was sampled); the collision itself is a vertex of
    // the next segment, so no flux is counted twice.
    const auto &segments = light.segments();
    std::vector<Beam> beams;
    beams.reserve(segments.size());
    for (const LightSegment &s : segments) {
        if (s.medium < 0) continue;
        Beam b;
        b.origin = s.origin;
        b.dir = s.dir;
        b.length = std::min(s.length, s.t_surface);
        b.power = s.power;
        b.medium = s.medium;
        b.depth = s.depth;
        beams.push_back(b);
    }
    bvh_.build(std::move(beams), radius, max_piece_length);
    stats_.beams += bvh_.beams().size();
    beam_scale_ = 1.0 / (2.0 * radius * double(light.paths_per_iteration()));
}

size_t PhotonBeams::begin_wave(int64_t iteration, const RayBuffers &out) {
    const Camera &cam = scene_->camera;
    const int64_t npix = int64_t(cam.width) * cam.height;
    active_.clear();
    shadow_.clear();
    if (max_depth_ == 0) return 0;  // Mitsuba: max_depth 0 renders black
    active_.resize(paths_.size());
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (int64_t i = 0; i < int64_t(paths_.size()); ++i) {
        BeamGatherPath &p = paths_[i];
        int64_t pixel = i % npix;
        int64_t sample = iteration * spp_per_iteration_ + i / npix;
        p = BeamGatherPath();
        // A stream key distinct from the light paths' (which use (seed, iteration, path)).
        p.rng = Sampler(stream_key(seed_ ^ 0x5bd1e995b5ull, uint64_t(sample), uint64_t(pixel)));
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
    return active_.size();
}

// BB1D over the camera segment [0, t_end) of path p in its medium.
RGB PhotonBeams::gather(BeamGatherPath &p, double t_end, MediumStats &local, uint64_t &pairs) const {
    RGB sum(0.0);
    // A beam of depth k gathered after p.depth surface events makes a path of
    // k + 1 + p.depth real events, which must stay below max_depth.
    int max_beam_depth = max_depth_ < 0 ? INT_MAX : max_depth_ - 2 - p.depth;
    if (max_beam_depth < 0 || bvh_.beams().empty()) return sum;
    const Medium &m = scene_->media[p.medium];
    const bool homogeneous = m.type == MediumType::Homogeneous;
    const Vec3 wo = -p.dir;
    bvh_.query(p.pos, p.dir, t_end, [&](int32_t index, const BeamHit &h) {
        const Beam &b = bvh_.beams()[index];
        if (b.medium != p.medium || b.depth > max_beam_depth) return;
        RGB weight;
        if (homogeneous) {
            // Camera transmittance in closed form; the short beam's Tr(s) / P(t > s)
            // with the hero-channel free-flight pdf of the light tracer.
            RGB beam_tr = beer_lambert(m.sigma_t, h.t_beam);
            double survival = mean(beam_tr);
            if (!(survival > 0)) return;
            weight = beer_lambert(m.sigma_t, h.t_ray) * m.sigma_t * m.albedo * beam_tr / survival;
        } else {
            // Gray extinction: both short-ray weights are 1.
            weight = m.albedo * grid_sigma_t(m, p.pos + p.dir * h.t_ray, local);
        }
        double phase = phase_eval(m.phase, wo, -b.dir);
        sum += weight * b.power * (phase / h.sin_theta);
        ++pairs;
    });
    return sum * beam_scale_;
}

size_t PhotonBeams::shade(const Hits &hits) {
    const Scene &scene = *scene_;
    uint64_t lookups = 0, pairs = 0;
    shadow_.rays.resize(hits.count);
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads_) reduction(+ : lookups, pairs)
    for (int64_t k = 0; k < int64_t(hits.count); ++k) {
        BeamGatherPath &p = paths_[active_[k]];
        shadow_.rays[k].live = false;
        int tri = hits.prim[k];
        double t_hit = tri >= 0 ? double(hits.tfar[k]) : kInf;

        if (p.medium >= 0) {
            MediumStats local;
            const Medium &m = scene.media[p.medium];
            if (!p.gathering) {
                // After a diffuse surface: path tracing, medium scattering included (as pt).
                FreeFlight ff = sample_free_flight(m, p.pos, p.dir, t_hit, p.rng, local);
                lookups += local.density_lookups;
                p.throughput *= ff.weight;
                if (ff.scattered) {
                    scatter_in_medium(p, k, p.pos + p.dir * ff.t);
                    continue;
                }
            } else if (m.type == MediumType::Homogeneous) {
                // Gather beams along the whole segment, then carry the transmittance to the surface.
                p.radiance += p.throughput * gather(p, t_hit, local, pairs);
                p.throughput *= beer_lambert(m.sigma_t, t_hit);
            } else {
                // Short query ray: a delta-tracked distance bounds the gather, and a
                // collision before the surface ends the camera path (beams covered it).
                FreeFlight ff = sample_free_flight(m, p.pos, p.dir, t_hit, p.rng, local);
                double t_end = ff.scattered ? ff.t : t_hit;
                p.radiance += p.throughput * gather(p, t_end, local, pairs);
                if (ff.scattered) p.alive = false;
            }
            lookups += p.gathering ? local.density_lookups : 0;
            if (!p.alive || is_black(p.throughput)) {
                p.alive = false;
                continue;
            }
        }
        if (tri < 0) {  // escaped: the scenes have no environment light
            p.alive = false;
            continue;
        }
        const Triangle &T = scene.triangles[tri];
        Vec3 x = T.point(hits.u[k], hits.v[k]);

        RGB Le = scene.emitted(tri, p.dir);
        if (!is_black(Le)) {
            double w = 1;
            if (!p.prev_delta) w = power_heuristic(p.prev_pdf, scene.area_light_pdf(tri, p.prev_pos, x));
            p.radiance += p.throughput * Le * w;
        }
        if (scene.materials[T.material].type == MaterialType::Null) {
            p.medium = T.medium_after(p.medium, p.dir);
            p.pos = scene.offset(x, tri, p.dir);
            p.alive = ++p.null_crossings < kMaxNullCrossingsPpb;
            continue;
        }
        scatter_on_surface(p, k, tri, x);
    }
    stats_.beam_pairs += pairs;
    stats_.density_lookups += lookups;
    size_t queued = 0;
    for (size_t k = 0; k < hits.count; ++k) queued += shadow_.rays[k].live;
    return queued;
}

void PhotonBeams::queue_shadow(BeamGatherPath &p, size_t slot, const LightSample &ls, const RGB &f,
                               double pdf_dir, const Vec3 &origin, int medium) {
    if (!ls.valid || is_black(f)) return;
    double w = ls.delta ? 1.0 : power_heuristic(ls.pdf, pdf_dir);
    ShadowRay &r = shadow_.rays[slot];
    r.dir = ls.wi;
    r.to_infinity = !std::isfinite(ls.dist);
    r.target = r.to_infinity ? Vec3() : ls.point;
    r.target_eps = r.to_infinity ? 0 : 2 * scene_->offset_length(ls.point);
    r.restart_at(origin);
    r.medium = medium;
    r.contribution = p.throughput * f * ls.value * w;
    r.rng = p.rng.split(uint64_t(p.depth));
    r.live = !is_black(r.contribution);
    r.receiver = int64_t(&p - paths_.data());
}

void PhotonBeams::scatter_in_medium(BeamGatherPath &p, size_t slot, const Vec3 &x) {
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
    p.dir = phase_sample(m.phase, wo, u1, u2, pdf);  // exact sampling: weight 1
    p.prev_pos = x;
    p.prev_pdf = pdf;
    p.prev_delta = false;
    p.pos = x;
    p.alive = russian_roulette(p);
}

// Radiance leaving diffuse triangle `tri` at x towards -p.dir from the photons
// within the surface radius; p.depth already counts the event at x.
RGB PhotonBeams::gather_photons(const BeamGatherPath &p, int tri, const Vec3 &x) const {
    RGB sum(0.0);
    const Triangle &T = scene_->triangles[tri];
    const Material &mat = scene_->materials[T.material];
    if (dot(-p.dir, T.n) <= 0) return sum;  // one-sided
    photon_tree_.query_sphere(x, photon_radius_, [&](size_t i, double) {
        const LightVertex &v = photons_[i];
        // The photon's vertex is x itself: v.depth + (p.depth - 1) events in all.
        if (max_depth_ >= 0 && v.depth + p.depth - 1 >= max_depth_) return;
        // Same surface orientation (photons across a corner or a thin wall belong elsewhere).
        if (dot(scene_->triangles[v.triangle].n, T.n) < 0.9 || dot(v.wi, T.n) <= 0) return;
        sum += v.power;
    });
    return sum * mat.reflectance * (kInvPi * photon_scale_);
}

void PhotonBeams::scatter_on_surface(BeamGatherPath &p, size_t slot, int tri, const Vec3 &x) {
    const Triangle &T = scene_->triangles[tri];
    const Material &mat = scene_->materials[T.material];
    if (++p.depth >= max_depth_ && max_depth_ >= 0) {
        p.alive = false;
        return;
    }
    Vec3 wo = -p.dir;
    if (surface_photons_ && !mat.is_delta()) {
        // The path ends here: direct light by NEE (full weight), the rest by photons.
        LightSample ls = scene_->sample_light(x, p.rng);
        if (ls.valid) {
            RGB f = bsdf_eval(mat, T.n, wo, ls.wi);
            LightSample full = ls;
            full.pdf = 0;
            full.delta = true;  // weight 1: no BSDF-sampled emission competes with it
            queue_shadow(p, slot, full, f, 0, scene_->offset(x, tri, ls.wi), T.medium_after(p.medium, ls.wi));
        }
        p.radiance += p.throughput * gather_photons(p, tri, x);
        p.alive = false;
        return;
    }
    if (!mat.is_delta()) {
        // Next-event estimation, power heuristic against BSDF sampling (as pt). Past
        // the last gathering bounce the path scatters in media itself.
        p.gathering = ++p.diffuse_bounces <= gather_diffuse_bounces_;
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

bool PhotonBeams::russian_roulette(BeamGatherPath &p) {
    if (p.depth <= rr_depth_) return true;
    double q = std::min(max_component(p.throughput) * p.eta2, 0.95);
    if (!(p.rng.next() < q)) return false;
    p.throughput = p.throughput / q;
    return true;
}

void PhotonBeams::resolve_shadows(const Hits &hits) {
    shadow_.resolve(*scene_, hits, threads_, medium_stats_, [&](int64_t path, const RGB &value) {
        paths_[path].radiance += value;  // one shadow ray per path at a time: no race
    });
}

size_t PhotonBeams::next_rays(const RayBuffers &out) {
    size_t n = 0;
    for (int32_t i : active_)
        if (paths_[i].alive) active_[n++] = i;
    active_.resize(n);
    for (size_t k = 0; k < n; ++k) {
        const BeamGatherPath &p = paths_[active_[k]];
        out.put(k, p.pos, p.dir, kInf);
    }
    return n;
}

void PhotonBeams::end_wave() {
    for (const BeamGatherPath &p : paths_) film_.add(p.pixel, p.radiance);
    film_.samples_per_pixel += spp_per_iteration_;
    active_.clear();
    stats_.density_lookups += medium_stats_.density_lookups;
    medium_stats_ = MediumStats();
}

}  // namespace pgi
