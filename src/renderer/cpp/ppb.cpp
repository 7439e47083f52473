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
      film_(scene_->camera.width, scene_->camera.height), bvh_(max_beams),
      schedules_(std::max<size_t>(1, scene_->media.size()), RadiusSchedule(radius, alpha, 1)) {
    paths_.resize(size_t(film_.width) * film_.height * spp_per_iteration_);
}

void ProgressivePhotonBeams::set_surface_photons(double radius, double alpha) {
    surface_photons_ = radius > 0;
    if (surface_photons_) surface_schedule_ = RadiusSchedule(radius, alpha, 2);
}

void ProgressivePhotonBeams::set_beam_radius(int medium, double radius) {
    if (medium < 0 || medium >= int(scene_->media.size())) throw std::out_of_range("ppb: no such medium");
    schedules_[size_t(medium)] = RadiusSchedule(radius, schedules_[0].alpha, 1);
}

const RadiusSchedule &ProgressivePhotonBeams::beam_schedule(int medium) const {
    if (medium < 0 || medium >= int(schedules_.size())) throw std::out_of_range("ppb: no such medium");
    return schedules_[size_t(medium)];
}

void ProgressivePhotonBeams::set_pilot(size_t surface_neighbours, size_t beam_neighbours, double extent_fraction,
                                       int64_t path_stride) {
    pilot_.set(surface_neighbours, beam_neighbours, extent_fraction, path_stride);
    if (!surface_photons_) pilot_.skip_surfaces();
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
        if (!pilot_.on()) {
            photon_radius_ = surface_schedule_.radius(iteration);
            photon_scale_ = 1.0 / (kPi * photon_radius_ * photon_radius_ * double(light.paths_per_iteration()));
            stats_.photons += photons_.size();
        }
    }
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
    active_.clear();
    shadow_.clear();
    if (pilot_.on()) {
        // The pilot: what each kernel could gather, a tree of radius 0 (kth_nearest grows its
        // boxes), and a regular sample of the paths.
        std::vector<BoundingBox> boxes(schedules_.size() + 1);
        for (const PathVertex &v : photons_) boxes[0].add(v.pos);
        for (const Beam &b : beams)
            if (std::isfinite(b.length) && size_t(b.medium) + 1 < boxes.size()) {
                boxes[size_t(b.medium) + 1].add(b.origin);
                boxes[size_t(b.medium) + 1].add(b.origin + b.dir * b.length);
            }
        pilot_.begin(boxes);
        bvh_.build(std::move(beams), 0.0, max_piece_length_);
        if (!depth_.allows(0)) return;
        start_camera_wave(paths_, active_, scene_->camera, iteration, spp_per_iteration_,
                          seed_ ^ stream_tag::kBeamGatherPaths, threads_);
        pilot_.sample_paths(paths_, active_);
        return;
    }
    beam_radii_.resize(schedules_.size());
    beam_scales_.resize(schedules_.size());
    for (size_t m = 0; m < schedules_.size(); ++m) {
        beam_radii_[m] = schedules_[m].radius(iteration);
        beam_scales_[m] = 1.0 / (2.0 * beam_radii_[m] * double(light.paths_per_iteration()));
    }
    bvh_.build(std::move(beams), beam_radii_, max_piece_length_);
    stats_.beams += bvh_.beams().size();

    if (!depth_.allows(0)) return;  // Mitsuba: max_depth 0 renders black
    // A stream key distinct from the light paths' (which use (seed, iteration, path)).
    start_camera_wave(paths_, active_, scene_->camera, iteration, spp_per_iteration_,
                      seed_ ^ stream_tag::kBeamGatherPaths, threads_);
}

namespace {

// Where the ray o + t d meets the beam b translated by u * blur (blur not in the plane of the
// two directions): the solution of t d - s b.dir - u blur = b.origin - o (Cramer's rule), and
// the determinant's magnitude, the estimate's Jacobian (sin(theta) for the common
// perpendicular). False if the system is (nearly) singular.
struct BlurredMeeting {
    double t, s, u, jacobian;
};
inline bool blurred_meeting(const Vec3 &o, const Vec3 &d, const Beam &b, const Vec3 &blur, BlurredMeeting &out) {
    const Vec3 w = b.origin - o, nb = -b.dir, nblur = -blur;
    const double det = dot(d, cross(nb, nblur));
    if (!(std::abs(det) > kMinBeamSine * kMinBeamSine)) return false;
    out.t = dot(w, cross(nb, nblur)) / det;
    out.s = dot(d, cross(w, nblur)) / det;
    out.u = dot(d, cross(nb, w)) / det;
    out.jacobian = std::abs(det);
    return true;
}

}  // namespace

// BB1D over the camera segment [0, t_end) of path p in its medium. Near the planes the segment
// starts and ends on, the blur lies in them (boundary_kernels.h): the common perpendicular m of
// ray and beam projected on the plane.
RGB ProgressivePhotonBeams::gather(BeamGatherPath &p, double t_end, const BoundaryPlane &exit, MediumStats &local,
                                   uint64_t &pairs) const {
    RGB sum(0.0);
    // A beam of depth k gathered after p.depth surface events makes a path of
    // k + 1 + p.depth real events; none is in range if one of depth 0 is not.
    if (!depth_.allows(1 + p.depth) || bvh_.beams().empty()) return sum;
    const Medium &m = scene_->media[p.medium];
    const bool homogeneous = m.type == MediumType::Homogeneous;
    const Vec3 wo = -p.dir;
    const double radius = beam_radii_[size_t(p.medium)];
    const KernelZones zones = kernel_zones(p.dir, t_end, radius, triangle_plane(*scene_, p.start_triangle, p.dir), exit);
    // t_end and the hits' t_ray count from the segment's origin, the lead behind p.pos.
    const Vec3 origin = segment_origin(p);
    // A pair: the camera point at t, the beam point at s, over the Jacobian of its blur.
    auto add = [&](const Beam &b, double t, double s, double jacobian) {
        RGB weight;
        if (homogeneous) {
            // Camera transmittance in closed form; the short beam's Tr(s) / P(t > s)
            // with the light path's hero-channel pdf (subpaths.h).
            RGB beam_tr = beer_lambert(m.sigma_t, s);
            double survival = mean(b.spectral_ratio * beam_tr);
            if (!(survival > 0)) return;
            weight = beer_lambert(m.sigma_t, t) * m.sigma_t * m.albedo * beam_tr / survival;
        } else {
            // Gray extinction: both short-ray weights are 1.
            weight = m.albedo * grid_sigma_t(m, origin + p.dir * t, local);
        }
        double phase = phase_eval(m.phase, wo, -b.dir);
        sum += weight * b.power * (phase / jacobian);
        ++pairs;
    };
    // In an aligned zone [t0, t1) with plane normal n: the blur along m projected on the plane.
    auto aligned = [&](const Beam &b, const BeamBvh::Piece &piece, const BoundaryPlane &plane, double t0, double t1) {
        Vec3 m_dir = cross(p.dir, b.dir);
        double sine = length(m_dir);
        if (!(sine > kMinBeamSine)) return;
        m_dir = m_dir / sine;
        Vec3 blur = m_dir - plane.normal * dot(m_dir, plane.normal);
        double blur_length = length(blur);
        if (!(blur_length > 0)) return;
        BlurredMeeting h;
        if (!blurred_meeting(origin, p.dir, b, blur / blur_length, h)) return;
        if (!(std::abs(h.u) < radius) || !(h.t >= t0 && h.t < t1) || !piece.holds(h.s)) return;
        add(b, h.t, h.s, h.jacobian);
    };
    bvh_.query_pieces(origin, p.dir, t_end, [&](const BeamBvh::Piece &piece) {
        // Lines farther apart than r meet neither kernel: the aligned blur moves the beam by
        // |u| = distance / (m.b) >= distance to meet the ray (and near-parallel pairs, which
        // closest_approach refuses, are refused by both). Tested on the piece's own copy of
        // the line before the beam is read: most pieces fail it, and reading each one's beam
        // first (a cache miss per piece) made ppb's iterations a quarter slower.
        BeamHit h;
        if (!closest_approach(piece.origin, piece.dir, origin, p.dir, h) || !(h.distance < radius)) return;
        const Beam &b = bvh_.beams()[size_t(piece.beam)];
        if (b.medium != p.medium || !depth_.allows(b.depth + 1 + p.depth)) return;
        if (piece.holds(h.t_beam)) {
            bool before_exit = zones.exit_start < t_end ? h.t_ray < zones.exit_start : h.t_ray <= t_end;
            if (h.t_ray >= zones.entry_end && before_exit) add(b, h.t_ray, h.t_beam, h.sin_theta);
        }
        if (zones.entry_end > 0) aligned(b, piece, zones.entry, 0.0, zones.entry_end);
        if (zones.exit_start < t_end) aligned(b, piece, zones.exit, zones.exit_start, t_end);
    });
    return sum * beam_scales_[size_t(p.medium)];
}

// Pilot: the distance within which the k nearest beams lie around the segment up to a free
// flight along it (pilot_flight); none where the flight crosses the segment.
double ProgressivePhotonBeams::pilot_beams(const BeamGatherPath &p, double t_end, Sampler rng, double &free_path) const {
    if (pilot_.medium_neighbours() == 0 || !depth_.allows(1 + p.depth)) return RadiusPilot::kNoRecord;
    const Vec3 origin = segment_origin(p);
    const PilotFlight flight = pilot_flight(scene_->media[p.medium], origin, p.dir, t_end, rng, p.rng);
    if (!std::isfinite(flight.t)) return RadiusPilot::kNoRecord;
    free_path = flight.free_path;
    return bvh_.kth_nearest(origin, p.dir, flight.t, pilot_.medium_neighbours(), pilot_.max_radius(p.medium),
                            [&](int32_t index) {
                                const Beam &b = bvh_.beams()[size_t(index)];
                                return b.medium == p.medium && depth_.allows(b.depth + 1 + p.depth);
                            });
}

// Pilot: the distance within which the k nearest surface photons of x's estimate lie.
double ProgressivePhotonBeams::pilot_photons(const BeamGatherPath &p, int tri, const Vec3 &x) const {
    const size_t k = pilot_.surface_neighbours();
    if (k == 0) return RadiusPilot::kNoRecord;
    return kth_nearest_surface_photon(*scene_, photon_tree_, photons_, tri, x, -p.dir, k, pilot_.max_radius(-1),
                                      RadiusPilot::kNoRecord,
                                      [&](const PathVertex &v) { return depth_.allows(v.depth + p.depth - 1); });
}

size_t ProgressivePhotonBeams::shade(const Hits &hits) {
    const Scene &scene = *scene_;
    hits.expect(active_.size(), "ppb shade");
    uint64_t lookups = 0, pairs = 0;
    shadow_.open(hits.count);
    const bool pilot = pilot_.on();
    if (pilot) pilot_.open_hits(hits.count);
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
            const BoundaryPlane exit = triangle_plane(scene, tri, p.dir);
            // The beams of [0, t_end), or (pilot) the distance to the k-th nearest.
            auto gather_or_measure = [&](double t_end, const BoundaryPlane &end_plane) {
                if (!pilot) {
                    p.radiance += p.throughput * gather(p, t_end, end_plane, local, pairs);
                    return;
                }
                double free_path = RadiusPilot::kNoRecord;
                const double distance = pilot_beams(p, t_end, p.rng.fork(), free_path);
                pilot_.record_segment(size_t(k), p.medium, distance, free_path);
            };
            if (!p.gathering) {
                // After a diffuse surface: path tracing, medium scattering included (as pt).
                bool scattered = steps_.fly_through_medium(p, shadow_[k], index, t_hit, local);
                lookups += local.density_lookups;
                if (scattered) {
                    p.start_triangle = -1;
                    continue;
                }
            } else if (m.type == MediumType::Homogeneous) {
                // Gather beams along the whole segment, then carry the transmittance to the surface.
                gather_or_measure(t_hit + p.lead, exit);
                p.throughput *= beer_lambert(m.sigma_t, t_hit + p.lead);
            } else {
                // Short query ray: a delta-tracked distance bounds the gather, and a
                // collision before the surface ends the camera path (beams covered it).
                FreeFlight ff = sample_free_flight(m, segment_origin(p), p.dir, t_hit + p.lead, p.rng, local,
                                                   p.spectral);  // a grid: gray, the ratios stay
                double t_end = ff.scattered ? ff.t : t_hit + p.lead;
                gather_or_measure(t_end, ff.scattered ? BoundaryPlane{} : exit);
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
        p.start_triangle = tri;  // the next ray leaves this surface (null boundary or scattering)
    }
    if (pilot) pilot_.close_hits();
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
        if (pilot_.on()) {
            pilot_.record_surface(slot, pilot_photons(p, tri, x));
        } else {
            steps_.next_event_on_surface(p, shadow, index, tri, x, /*mis=*/false);
            p.radiance += p.throughput * gather_photons(p, tri, x);
        }
        p.alive = false;
        return;
    }
    if (!mat.is_delta()) {
        // Next-event estimation as pt. Past the last gathering bounce the path
        // scatters in media itself.
        p.gathering = ++p.diffuse_bounces <= gather_diffuse_bounces_;
        if (!pilot_.on()) steps_.next_event_on_surface(p, shadow, index, tri, x);
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
    if (!pilot_.on()) add_paths_to_film(film_, paths_, spp_per_iteration_);  // a pilot estimates nothing
    active_.clear();
    stats_.density_lookups += medium_stats_.density_lookups;
    medium_stats_ = MediumStats();
}

}  // namespace pgi
