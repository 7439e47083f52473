// Subpaths from the lights and from the camera (see subpaths.h for the API and the meaning of
// records).
#include "subpaths.h"

#include <numeric>
#include <stdexcept>
#include <string>

namespace pgi {

template <Side S>
Subpaths<S>::Subpaths(std::shared_ptr<const Scene> scene, int max_depth, int rr_depth, uint64_t seed,
                      int64_t paths_per_iteration, int threads, int64_t max_records)
    : scene_(std::move(scene)), depth_(max_depth), rr_depth_(rr_depth), seed_(seed),
      threads_(std::max(1, threads)), max_records_(max_records) {
    if (paths_per_iteration <= 0) throw std::invalid_argument("paths_per_iteration must be positive");
    if constexpr (S == Side::Camera) {
        camera_spp_ = int(paths_per_iteration);
        paths_per_iteration *= int64_t(scene_->camera.width) * scene_->camera.height;
    }
    paths_.resize(size_t(paths_per_iteration));
}

template <Side S>
void Subpaths<S>::check_capacity() const {
    int64_t records = int64_t(vertices_.size() + segments_.size());
    if (max_records_ > 0 && records > max_records_)
        throw std::length_error(std::string(S == Side::Light ? "light" : "camera") + " paths: " + std::to_string(records) +
                                " records exceed the configured bound of " + std::to_string(max_records_));
}

template <Side S>
void Subpaths<S>::begin(int64_t iteration) {
    iteration_ = iteration;
    vertices_.clear();
    segments_.clear();
    active_.clear();
    const Scene &scene = *scene_;
    // max_depth 0 renders black: not even a light seen directly is in range.
    if (!depth_.allows(0) || scene.light_selection.size() == 0 || scene.light_selection.total() <= 0) return;
    size_t n = paths_.size();
    slot_vertex_.resize(n);
    slot_segment_.resize(n);
    slot_has_vertex_.assign(n, 0);
    slot_has_segment_.assign(n, 0);
    tracks_.resize(complete_ ? n : 0);
#pragma omp parallel for schedule(static) num_threads(threads_)
    for (int64_t i = 0; i < int64_t(n); ++i) {
        SubpathState &p = paths_[i];
        if constexpr (S == Side::Camera) {
            start_at_camera(p, size_t(i), iteration);
        } else {
            p = SubpathState();
            p.rng = Sampler(stream_key(seed_ ^ stream_tag::kLightPaths, uint64_t(iteration), uint64_t(i)));
            p.spectral.hero = hero_channel(p.rng);
            emit(p, size_t(i));
        }
    }
    paths_traced_ += n;
    collect(n, [](size_t slot) { return slot; });
    active_.resize(n);
    std::iota(active_.begin(), active_.end(), 0);
}

// A path from a point or spot light starts its clearance out along its direction, as
// pt's shadow rays stop as far short of the light: a light placed on a surface (a lamp on
// the ceiling) then lights the room instead of hitting its own wall at distance 0. The
// medium the light sits in fills that gap: it is the path's lead.
static RayStart off_the_light(const Scene &scene, const Vec3 &position, const Vec3 &dir) {
    const double clearance = scene.light_clearance(position);
    return {position + dir * clearance, clearance};
}

// Emission: a light by power, then a point and a direction on it (Jensen 2001, ch. 5).
EmissionSample sample_emission(const Scene &scene, const double u[6]) {
    EmissionSample s;
    if (scene.light_selection.size() == 0 || scene.light_selection.total() <= 0) return s;
    size_t li = scene.light_selection.sample(u[0]);
    double pick = scene.light_selection.pmf(li);
    if (!(pick > 0)) return s;
    s.light = int(li);
    const Light &l = scene.lights[li];
    switch (l.type) {
        case LightType::Area: {
            // Point uniform by area, direction cosine-weighted on the front side:
            // power = Le cos / (pdf_A * cos / pi) = Le * pi * A / pick.
            const AreaEmitter &e = scene.area_emitters[l.emitter];
            s.triangle = e.triangles[e.by_area.sample(u[1])];
            const Triangle &T = scene.triangles[s.triangle];
            double b1, b2;
            square_to_triangle(u[2], u[3], b1, b2);
            s.pos = T.point(b1, b2);
            s.vertex_power = e.radiance * (e.area / pick);
            s.pdf_pos = pick / e.area;
            Vec3 local = square_to_cosine_hemisphere(u[4], u[5]);
            if (local.z <= 0) return s;
            s.dir = Frame(T.n).to_world(local);
            s.power = e.radiance * (kPi * (e.area / pick));
            s.pdf_dir = local.z * kInvPi;
            break;
        }
        case LightType::Point:
            s.pos = l.position;
            s.dir = square_to_uniform_sphere(u[4], u[5]);
            s.power = l.intensity * (4 * kPi / pick);
            s.vertex_power = l.intensity / pick;
            s.pdf_pos = pick;
            s.pdf_dir = kInv4Pi;
            break;
        case LightType::Spot: {
            // Uniform in the cutoff cone, weighted by the falloff.
            s.pos = l.position;
            s.dir = square_to_uniform_cone(l.direction, l.cos_cutoff, u[4], u[5]);
            s.power = l.intensity * (l.spot_falloff(s.dir) / (square_to_uniform_cone_pdf(l.cos_cutoff) * pick));
            s.vertex_power = l.intensity / pick;
            s.pdf_pos = pick;
            s.pdf_dir = square_to_uniform_cone_pdf(l.cos_cutoff);
            break;
        }
        case LightType::Directional: {
            // A disk covering the scene's bounding sphere, just outside it, perpendicular to
            // the direction of travel: power = E * area / pick, the unit disk's pdf scaled by R^2.
            const Scene::Disk sun = scene.directional_disk(l.direction);
            const double radius = sun.radius;
            Vec3 disk = square_to_uniform_disk_concentric(u[4], u[5]);
            Frame f(l.direction);
            s.pos = sun.centre + (f.s * disk.x + f.t * disk.y) * radius;
            s.dir = l.direction;
            s.power = l.intensity * (radius * radius / (square_to_uniform_disk_concentric_pdf() * pick));
            s.vertex_power = l.intensity / pick;
            s.pdf_pos = pick;  // of the delta direction; the disk's density goes to the next vertex
            s.pdf_dir = square_to_uniform_disk_concentric_pdf() / (radius * radius);
            break;
        }
    }
    s.has_direction = true;
    return s;
}

// A camera sample: path `slot` samples pixel slot % pixels, with its stream keyed by (seed,
// sample, pixel) as pt's are (camera_path.h); its first vertex is the camera.
template <Side S>
void Subpaths<S>::start_at_camera(SubpathState &p, size_t slot, int64_t iteration) {
    const Camera &cam = scene_->camera;
    start_camera_sample(p, cam, int64_t(slot), iteration, camera_spp_, seed_ ^ stream_tag::kCameraPaths);
    p.power = RGB(1.0);
    PathVertex &v = record_vertex(slot, p, VertexKind::Camera, cam.origin, Vec3(0.0));
    v.pdf_fwd = 1;
    DensityTrack &t = track(p);
    t = DensityTrack{};
    t.last.pos = t.piece_start = cam.origin;
    t.last.normal = normalize(cam.forward);
    t.last.sampling = DensityVertex::Sampling::Camera;
    p.alive = depth_.allows(1);
}

template <Side S>
void Subpaths<S>::emit(SubpathState &p, size_t slot) {
    const Scene &scene = *scene_;
    double u[6];
    for (double &v : u) v = p.rng.next();
    const EmissionSample e = sample_emission(scene, u);
    if (e.light < 0) return;
    const Light &l = scene.lights[e.light];
    const bool area = l.type == LightType::Area;
    if (area ? record_vertices_ : complete_) {
        // The light's own vertex: wi holds an area light's normal, a spot's axis or a
        // directional light's direction of travel.
        const Vec3 wi = area ? scene.triangles[e.triangle].n : l.direction;
        PathVertex &v = record_vertex(slot, p, VertexKind::Emission, e.pos, wi);
        v.throughput = e.vertex_power;
        v.light = int16_t(e.light);
        if (area) {
            const Triangle &T = scene.triangles[e.triangle];
            v.triangle = e.triangle;
            v.medium = T.transition ? T.exterior : scene.triangle_emission_medium(e.triangle);
        } else {
            v.medium = scene.light_emission_medium(e.light);
        }
        if (complete_) {
            v.pdf_fwd = e.pdf_pos;
            v.delta = !area;  // a point or spot light's position, a directional light's direction
        }
    }
    if (!e.has_direction) return;
    if (area) {
        const Triangle &T = scene.triangles[e.triangle];
        start_path_at(p, scene.spawn(e.pos, e.triangle, e.dir));
        p.medium = T.transition ? T.medium_after(-1, e.dir) : scene.triangle_emission_medium(e.triangle);
    } else {
        // A point or spot light's path starts off the light; a directional light's on its disk.
        start_path_at(p, l.type == LightType::Directional ? RayStart{e.pos, 0.0}
                                                           : off_the_light(scene, e.pos, e.dir));
        p.medium = scene.light_emission_medium(e.light);
    }
    p.dir = e.dir;
    p.power = e.power;
    if (complete_) {
        DensityTrack &t = track(p);
        t = DensityTrack{};
        DensityVertex &light = t.last;  // recorded above: collect gives it its record
        light.pos = t.piece_start = e.pos;
        light.pdf_dir = e.pdf_dir;
        if (area) {
            light.normal = scene.triangles[e.triangle].n;
            light.sampling = DensityVertex::Sampling::Cosine;
        }
        light.at_infinity = l.type == LightType::Directional;
        light.delta_light = !area;
    }
    double peak = max_component(p.power);
    if (!(peak > 0) || !is_finite(p.power)) return;
    p.inv_initial = 1 / peak;
    p.alive = depth_.allows(1);
}

template <Side S>
size_t Subpaths<S>::shade(const Hits &hits) {
    const Scene &scene = *scene_;
    hits.expect(active_.size(), "light-path scatter");
    uint64_t lookups = 0;
    size_t n = hits.count;
    slot_has_vertex_.assign(n, 0);
    slot_has_segment_.assign(n, 0);
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads_) reduction(+ : lookups)
    for (int64_t k = 0; k < int64_t(n); ++k) {
        SubpathState &p = paths_[active_[k]];
        int tri = hits.prim[k];
        double t_hit = tri >= 0 ? double(hits.tfar[k]) : kInf;
        if (p.medium >= 0) {
            MediumStats local;
            // The segment's record takes the ratios before this flight folds its pdf in.
            const RGB ratio_at_origin = p.spectral.ratio;
            FreeFlight ff = sample_free_flight(scene.media[p.medium], segment_origin(p), p.dir, t_hit + p.lead,
                                               p.rng, local, p.spectral);
            // A point on this segment scatters into a vertex of depth p.depth + 1.
            if (record_segments_ && depth_.allows(p.depth + 1)) {
                MediumSegment &s = slot_segment_[k];
                s.origin = segment_origin(p);
                s.dir = p.dir;
                s.length = ff.scattered ? ff.t : t_hit + p.lead;
                s.t_surface = t_hit + p.lead;
                s.power = p.power;
                s.spectral_ratio = ratio_at_origin;
                s.path = active_[k];
                s.medium = p.medium;
                s.depth = int16_t(p.depth);
                s.scattered = ff.scattered;
                slot_has_segment_[k] = 1;
            }
            if (complete_) {
                // The stand-in optical depth of this piece of the straight line from the last
                // vertex; the next piece starts where this one ends.
                DensityTrack &t = track(p);
                const Vec3 end = ff.scattered ? segment_point(p, ff.t)
                                 : tri >= 0   ? scene.triangles[tri].point(hits.u[k], hits.v[k])
                                              : t.piece_start + p.dir * kInf;
                const Vec3 to = end - t.piece_start;
                const double piece = is_finite(to) ? length(to) : kInf;  // escaping: infinite
                if (piece > 0)
                    t.flight_tau += flight_depth(scene.media[p.medium], t.piece_start,
                                                 piece < kInf ? to / piece : p.dir, piece);
                t.piece_start = end;
            }
            p.power *= ff.weight;
            if (ff.scattered) scatter_in_medium(p, size_t(k), segment_point(p, ff.t), local);
            lookups += local.density_lookups;
            if (ff.scattered) continue;
        }
        if (tri < 0) {
            p.alive = false;
            continue;
        }
        const Triangle &T = scene.triangles[tri];
        Vec3 x = T.point(hits.u[k], hits.v[k]);
        if (scene.materials[T.material].type == MaterialType::Null) {
            cross_null_boundary(scene, p, tri, x);
            if (complete_) track(p).piece_start = x;
            continue;
        }
        scatter_on_surface(p, size_t(k), tri, x);
    }
    stats_.density_lookups += lookups;
    collect(n, [&](size_t slot) { return size_t(active_[slot]); });
    return 0;
}

template <Side S>
void Subpaths<S>::scatter_in_medium(SubpathState &p, size_t slot, const Vec3 &x, MediumStats &stats) {
    const Medium &m = scene_->media[p.medium];
    ++p.depth;
    Vec3 wi = -p.dir;
    PathVertex *record = nullptr;
    if (record_vertices_ && depth_.allows(p.depth)) record = &record_vertex(slot, p, VertexKind::Medium, x, wi);
    if (complete_) {
        DensityVertex v;
        v.pos = x;
        v.sigma = flight_sigma(m, x, stats);
        v.medium = p.medium;
        v.sampling = DensityVertex::Sampling::Phase;
        advance_densities(p, v, record);
    }
    if (!depth_.allows(p.depth + 1)) {
        p.alive = false;
        return;
    }
    advance_by_phase(m, p, x);
    p.after_specular = false;
    p.alive = russian_roulette(p);
}

template <Side S>
void Subpaths<S>::scatter_on_surface(SubpathState &p, size_t slot, int tri, const Vec3 &x) {
    const Triangle &T = scene_->triangles[tri];
    const Material &mat = scene_->materials[T.material];
    ++p.depth;
    Vec3 wi = -p.dir;
    const bool lit = dot(wi, T.n) > 0;  // one-sided surfaces absorb light from behind
    // Connectible vertices: non-delta surfaces lit from the front. Complete subpaths also keep
    // delta ones (a dielectric from either side).
    const bool kept = complete_ ? lit || mat.type == MaterialType::Dielectric : lit && !mat.is_delta();
    PathVertex *record = nullptr;
    if (record_vertices_ && kept && depth_.allows(p.depth)) {
        record = &record_vertex(slot, p, VertexKind::Surface, x, wi);
        record->triangle = tri;
        record->delta = complete_ && mat.is_delta();
    }
    if (complete_) {
        DensityVertex v;
        v.pos = x;
        v.normal = T.n;
        if (mat.type == MaterialType::Diffuse) {
            v.sampling = DensityVertex::Sampling::Cosine;
        } else if (mat.type == MaterialType::Dielectric) {
            v.sampling = DensityVertex::Sampling::Dielectric;
            v.pdf_dir = mat.ior;
        } else {
            v.pdf_dir = 1;  // a mirror reflects with probability 1
        }
        advance_densities(p, v, record);
    }
    if (!depth_.allows(p.depth + 1)) {
        p.alive = false;
        return;
    }
    // Light paths carry importance (adjoint transport: no 1/eta^2 on refraction), camera paths
    // radiance.
    const BsdfSample bs = advance_by_bsdf(*scene_, p, p.power, tri, x, /*radiance=*/S == Side::Camera);
    if (!bs.valid) return;
    if constexpr (S == Side::Camera) p.eta2 *= bs.eta * bs.eta;
    p.after_specular = bs.delta;
    p.alive = russian_roulette(p);
}

// After rr_depth real events, survive_roulette on max(power) / max(emitted) for light paths,
// on max(throughput) eta^2 for camera paths (as pt's).
template <Side S>
bool Subpaths<S>::russian_roulette(SubpathState &p) {
    if (is_black(p.power)) return false;
    if (p.depth <= rr_depth_) return true;
    const double q = max_component(p.power) * (S == Side::Camera ? p.eta2 : p.inv_initial);
    return survive_roulette(p.power, q, p.rng, scene_->roulette);
}

// Slot `slot`'s vertex: path p at x, arrived from wi, with its power, medium, depth and
// specular flag as they are now; the caller adds what its kind needs (a triangle).
template <Side S>
PathVertex &Subpaths<S>::record_vertex(size_t slot, const SubpathState &p, VertexKind kind, const Vec3 &x,
                                       const Vec3 &wi) {
    PathVertex &v = slot_vertex_[slot];
    v = PathVertex();
    v.pos = x;
    v.wi = wi;
    v.throughput = p.power;
    v.path = int32_t(&p - paths_.data());
    v.medium = p.medium;
    v.depth = int16_t(p.depth);
    v.kind = kind;
    v.after_specular = p.after_specular;
    slot_has_vertex_[slot] = 1;
    return v;
}

// The density with which the path sampled x from its last vertex.
template <Side S>
double Subpaths<S>::forward_density(const DensityTrack &t, const DensityVertex &x) const {
    return vertex_density(*scene_, t.last, t.last.wi, x, x.tau_in);
}

// The vertex before the last one as a walk coming the other way, from x through the last
// vertex, would sample it. A light's delta position or direction cannot be sampled so: 0.
template <Side S>
void Subpaths<S>::reverse_density(const DensityTrack &t, const DensityVertex &x) {
    const DensityVertex &last = t.last, &before = t.before;
    if (before.record < 0) return;
    PathVertex &prev = vertices_[size_t(before.record)];
    const Vec3 from = x.pos - last.pos;
    const double f2 = dot(from, from);
    prev.pdf_rev = before.delta_light || !(f2 > 0)
                       ? 0.0
                       : vertex_density(*scene_, last, from / std::sqrt(f2), before, last.tau_in);
}

// A new vertex x of a complete subpath (`record`: its record, if kept): its forward density,
// the reverse density of the vertex two back, and x becomes the last vertex.
template <Side S>
void Subpaths<S>::advance_densities(SubpathState &p, DensityVertex x, PathVertex *record) {
    DensityTrack &t = track(p);
    const Vec3 to_last = t.last.pos - x.pos;
    x.wi = t.last.at_infinity ? -p.dir : to_last / length(to_last);
    x.tau_in = t.flight_tau;
    if (record) {
        record->wi = x.wi;  // as the densities take it: from the recorded positions
        record->tau_in = x.tau_in;
        record->pdf_fwd = forward_density(t, x);
    }
    reverse_density(t, x);
    t.before = t.last;
    t.last = x;  // its record index comes in collect
    t.flight_tau = 0;
    t.piece_start = x.pos;
}

template <Side S>
template <typename PathOf>
void Subpaths<S>::collect(size_t slots, PathOf &&path_of) {
    for (size_t k = 0; k < slots; ++k) {
        if (slot_has_segment_[k]) segments_.push_back(slot_segment_[k]);
        if (slot_has_vertex_[k]) {
            vertices_.push_back(slot_vertex_[k]);
            if (complete_) tracks_[path_of(k)].last.record = int64_t(vertices_.size()) - 1;
        }
    }
    check_capacity();
}

template <Side S>
size_t Subpaths<S>::next_rays(const RayBuffers &out) {
    return write_alive_rays(active_, paths_, out, threads_);
}

template class Subpaths<Side::Light>;
template class Subpaths<Side::Camera>;

}  // namespace pgi
