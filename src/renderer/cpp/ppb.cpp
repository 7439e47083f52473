// ppb: progressive photon beams (Jarosz et al. 2011; see ppb.h for the papers and the passes).
#include "ppb.h"

namespace pgi {

ProgressivePhotonBeams::ProgressivePhotonBeams(std::shared_ptr<const Scene> scene,
                                               std::shared_ptr<const LightPaths> light_paths, int max_depth,
                                               int rr_depth, uint64_t seed, int spp_per_iteration, int threads,
                                               size_t max_beams, double radius, double alpha,
                                               double max_piece_length, int gather_diffuse_bounces)
    : scene_(std::move(scene)), light_paths_(std::move(light_paths)), steps_(*scene_, max_depth, rr_depth),
      depth_(max_depth), seed_(seed), spp_per_iteration_(std::max(1, spp_per_iteration)),
      threads_(std::max(1, threads)), max_piece_length_(max_piece_length),
      gather_diffuse_bounces_(gather_diffuse_bounces),
      film_(scene_->camera.width, scene_->camera.height), bvh_(max_beams), schedule_(radius, alpha, 1) {
    paths_.resize(size_t(film_.width) * film_.height * spp_per_iteration_);
}

void ProgressivePhotonBeams::set_surface_photons(double radius, double alpha) {
    surface_photons_ = radius > 0;
    if (surface_photons_) surface_schedule_ = RadiusSchedule(radius, alpha, 2);
}

void ProgressivePhotonBeams::begin(int64_t iteration) {
    const LightPaths &light = *light_paths_;
    if (light.iteration() != iteration)
        throw std::logic_error("ppb: the light paths of iteration " + std::to_string(iteration) + " come first");
    if (surface_photons_) {
        // Direct light is next-event estimated: keep photons with depth >= 2.
        photons_.clear();
        std::vector<Vec3> points;
        for (const PathVertex &v : light.vertices())
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
    for (const MediumSegment &s : segments) {
        if (s.medium < 0) continue;
        Beam b;
        b.origin = s.origin;
        b.dir = s.dir;
        b.length = std::min(s.length, s.t_surface);
        b.power = s.power;
        b.spectral_ratio = s.spectral_ratio;
        b.medium = s.medium;
        b.depth = s.depth;
        beams.push_back(b);
    }
    bvh_.build(std::move(beams), radius, max_piece_length_);
    stats_.beams += bvh_.beams().size();
    beam_scale_ = 1.0 / (2.0 * radius * double(light.paths_per_iteration()));

    active_.clear();
    shadow_.clear();
    if (!depth_.allows(0)) return;  // Mitsuba: max_depth 0 renders black
    // A stream key distinct from the light paths' (which use (seed, iteration, path)).
    start_camera_wave(paths_, active_, scene_->camera, iteration, spp_per_iteration_,
                      seed_ ^ stream_tag::kBeamGatherPaths, threads_);
}

// BB1D over the camera segment [0, t_end) of path p in its medium.
RGB ProgressivePhotonBeams::gather(BeamGatherPath &p, double t_end, MediumStats &local, uint64_t &pairs) const {
    RGB sum(0.0);
    // A beam of depth k gathered after p.depth surface events makes a path of
    // k + 1 + p.depth real events; none is in range if one of depth 0 is not.
    if (!depth_.allows(1 + p.depth) || bvh_.beams().empty()) return sum;
    const Medium &m = scene_->media[p.medium];
    const bool homogeneous = m.type == MediumType::Homogeneous;
    const Vec3 wo = -p.dir;
    // t_end and the hits' t_ray count from the segment's origin, the lead behind p.pos.
    const Vec3 origin = segment_origin(p);
    bvh_.query(origin, p.dir, t_end, [&](int32_t index, const BeamHit &h) {
        const Beam &b = bvh_.beams()[index];
        if (b.medium != p.medium || !depth_.allows(b.depth + 1 + p.depth)) return;
        RGB weight;
        if (homogeneous) {
            // Camera transmittance in closed form; the short beam's Tr(s) / P(t > s)
            // with the light path's hero-channel pdf (subpaths.h).
            RGB beam_tr = beer_lambert(m.sigma_t, h.t_beam);
            double survival = mean(b.spectral_ratio * beam_tr);
            if (!(survival > 0)) return;
            weight = beer_lambert(m.sigma_t, h.t_ray) * m.sigma_t * m.albedo * beam_tr / survival;
        } else {
            // Gray extinction: both short-ray weights are 1.
            weight = m.albedo * grid_sigma_t(m, origin + p.dir * h.t_ray, local);
        }
        double phase = phase_eval(m.phase, wo, -b.dir);
        sum += weight * b.power * (phase / h.sin_theta);
        ++pairs;
    });
    return sum * beam_scale_;
}

size_t ProgressivePhotonBeams::shade(const Hits &hits) {
    const Scene &scene = *scene_;
    hits.expect(active_.size(), "ppb shade");
    uint64_t lookups = 0, pairs = 0;
    shadow_.open(hits.count);
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads_) reduction(+ : lookups, pairs)
    for (int64_t k = 0; k < int64_t(hits.count); ++k) {
        const int64_t index = active_[k];
        BeamGatherPath &p = paths_[index];
        shadow_[k].live = false;
        int tri = hits.prim[k];
        double t_hit = tri >= 0 ? double(hits.tfar[k]) : kInf;

        if (p.medium >= 0) {
            MediumStats local;
            const Medium &m = scene.media[p.medium];
            if (!p.gathering) {
                // After a diffuse surface: path tracing, medium scattering included (as pt).
                bool scattered = steps_.fly_through_medium(p, shadow_[k], index, t_hit, local);
                lookups += local.density_lookups;
                if (scattered) continue;
            } else if (m.type == MediumType::Homogeneous) {
                // Gather beams along the whole segment, then carry the transmittance to the surface.
                p.radiance += p.throughput * gather(p, t_hit + p.lead, local, pairs);
                p.throughput *= beer_lambert(m.sigma_t, t_hit + p.lead);
            } else {
                // Short query ray: a delta-tracked distance bounds the gather, and a
                // collision before the surface ends the camera path (beams covered it).
                FreeFlight ff = sample_free_flight(m, segment_origin(p), p.dir, t_hit + p.lead, p.rng, local,
                                                   p.spectral);  // a grid: gray, the ratios stay
                double t_end = ff.scattered ? ff.t : t_hit + p.lead;
                p.radiance += p.throughput * gather(p, t_end, local, pairs);
                if (ff.scattered) p.alive = false;
            }
            lookups += p.gathering ? local.density_lookups : 0;
            if (!p.alive || is_black(p.throughput)) {
                p.alive = false;
                continue;
            }
        }
        Vec3 x;
        if (steps_.reach_surface(p, tri, hits.u[k], hits.v[k], x)) scatter_on_surface(p, k, tri, x);
    }
    stats_.beam_pairs += pairs;
    stats_.density_lookups += lookups;
    return shadow_.live(threads_);
}

// Radiance leaving diffuse triangle `tri` at x towards -p.dir from the photons
// within the surface radius; p.depth already counts the event at x.
RGB ProgressivePhotonBeams::gather_photons(const BeamGatherPath &p, int tri, const Vec3 &x) const {
    // The photon's vertex is x itself: v.depth + (p.depth - 1) events in all.
    RGB reflected = reflected_photon_power(*scene_, photon_tree_, photons_, tri, x, -p.dir, photon_radius_,
                                           [&](const PathVertex &v) {
                                               return depth_.allows(v.depth + p.depth - 1);
                                           });
    return reflected * photon_scale_;
}

void ProgressivePhotonBeams::scatter_on_surface(BeamGatherPath &p, size_t slot, int tri, const Vec3 &x) {
    const Triangle &T = scene_->triangles[tri];
    const Material &mat = scene_->materials[T.material];
    if (!steps_.count_event(p)) return;
    ShadowRay &shadow = shadow_[slot];
    const int64_t index = int64_t(&p - paths_.data());
    if (surface_photons_ && !mat.is_delta()) {
        // The path ends here: direct light by NEE (full weight), the rest by photons.
        steps_.next_event_on_surface(p, shadow, index, tri, x, /*mis=*/false);
        p.radiance += p.throughput * gather_photons(p, tri, x);
        p.alive = false;
        return;
    }
    if (!mat.is_delta()) {
        // Next-event estimation as pt. Past the last gathering bounce the path
        // scatters in media itself.
        p.gathering = ++p.diffuse_bounces <= gather_diffuse_bounces_;
        steps_.next_event_on_surface(p, shadow, index, tri, x);
    }
    steps_.continue_by_bsdf(p, tri, x);
}

void ProgressivePhotonBeams::resolve_shadows(const Hits &hits) {
    shadow_.resolve(*scene_, hits, threads_, medium_stats_, [&](int64_t path, const RGB &value) {
        paths_[path].radiance += value;  // one shadow ray per path at a time: no race
    });
}

size_t ProgressivePhotonBeams::next_rays(const RayBuffers &out) { return write_alive_rays(active_, paths_, out, threads_); }

void ProgressivePhotonBeams::end() {
    add_paths_to_film(film_, paths_, spp_per_iteration_);
    active_.clear();
    stats_.density_lookups += medium_stats_.density_lookups;
    medium_stats_ = MediumStats();
}

}  // namespace pgi
