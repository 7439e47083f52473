// bdpt: bidirectional path tracing (see bdpt.h for the papers, the strategies and the weights).
#include "bdpt.h"

#include <stdexcept>
#include <string>

#include "lt.h"  // connect_to_camera: the pinhole's importance, shared with light tracing

namespace pgi {

namespace {

// A vertex a connection can join: a non-delta surface or a medium vertex (never the camera's
// or a light's own: the strategies s = 0, s = 1 and t = 1 treat those).
bool connectible(const Scene &scene, const PathVertex &v) {
    if (v.kind == VertexKind::Medium) return true;
    return v.kind == VertexKind::Surface && !scene.materials[scene.triangles[v.triangle].material].is_delta();
}

// The BSDF times |cos| towards `out`, or the phase function, at v for light or importance that
// reached it from v.wi.
RGB scattering(const Scene &scene, const PathVertex &v, const Vec3 &out) {
    if (v.kind == VertexKind::Medium) return RGB(phase_eval(scene.media[v.medium].phase, v.wi, out));
    const Triangle &T = scene.triangles[v.triangle];
    return bsdf_eval(scene.materials[T.material], T.n, v.wi, out);
}

// Where a shadow ray from vertex v towards `dir` starts, and in which medium.
RayStart shadow_start(const Scene &scene, const PathVertex &v, const Vec3 &dir, int &medium) {
    medium = v.medium;
    if (v.kind == VertexKind::Medium || v.triangle < 0) return RayStart{v.pos};
    const Triangle &T = scene.triangles[v.triangle];
    medium = v.kind == VertexKind::Emission ? medium : T.medium_after(v.medium, dir);
    return scene.spawn(v.pos, v.triangle, dir);
}

// How far short of vertex v a ray aimed at it stops: an offset before a surface, nothing in a
// medium.
double stop_short(const Scene &scene, const PathVertex &v) {
    return v.kind == VertexKind::Medium ? 0.0 : scene.offset_length(v.pos);
}

}  // namespace

BidirectionalPathTracing::BidirectionalPathTracing(std::shared_ptr<const Scene> scene,
                                                   std::shared_ptr<const LightPaths> light_paths,
                                                   std::shared_ptr<const CameraPaths> camera_paths, int max_depth,
                                                   uint64_t seed, int spp_per_iteration, int threads, int max_connect)
    : scene_(std::move(scene)), light_paths_(std::move(light_paths)), camera_paths_(std::move(camera_paths)),
      depth_(max_depth), seed_(seed), spp_(std::max(1, spp_per_iteration)), threads_(std::max(1, threads)),
      max_connect_(std::max(2, max_connect)), film_(scene_->camera.width, scene_->camera.height) {
    if (light_paths_->paths_per_iteration() != camera_paths_->paths_per_iteration())
        throw std::invalid_argument("bdpt: one light subpath per camera sample");
    if (!light_paths_->complete() || !camera_paths_->complete())
        throw std::invalid_argument("bdpt: the subpaths must be recorded complete");
    shadow_.track_flights(true);
}

BidirectionalPathTracing::Subpath BidirectionalPathTracing::light_subpath(int64_t k) const {
    return {light_order_.data() + light_first_[k], int(light_first_[k + 1] - light_first_[k])};
}

BidirectionalPathTracing::Subpath BidirectionalPathTracing::camera_subpath(int64_t k) const {
    return {camera_order_.data() + camera_first_[k], int(camera_first_[k + 1] - camera_first_[k])};
}

// Each subpath's vertices, in depth order: the records come bounce by bounce with paths in
// ascending order, so a stable bucketing by path keeps every path's vertices by depth.
static void order_by_path(const std::vector<PathVertex> &records, int64_t paths, std::vector<const PathVertex *> &order,
                          std::vector<int64_t> &first) {
    first.assign(size_t(paths) + 1, 0);
    for (const PathVertex &v : records) ++first[size_t(v.path) + 1];
    for (size_t k = 0; k < size_t(paths); ++k) first[k + 1] += first[k];
    std::vector<int64_t> next(first.begin(), first.end() - 1);
    order.resize(records.size());
    for (const PathVertex &v : records) order[size_t(next[size_t(v.path)]++)] = &v;
}

void BidirectionalPathTracing::begin(int64_t iteration) {
    if (light_paths_->iteration() != iteration || camera_paths_->iteration() != iteration)
        throw std::logic_error("bdpt: the subpaths of iteration " + std::to_string(iteration) + " come first");
    iteration_ = iteration;
    const int64_t n = camera_paths_->paths_per_iteration();
    order_by_path(light_paths_->vertices(), n, light_order_, light_first_);
    order_by_path(camera_paths_->vertices(), n, camera_order_, camera_first_);
    // Count every sample's strategies, place them, then fill them (both in parallel): the
    // connections of one sample are contiguous and in a fixed order.
    first_connection_.assign(size_t(n) + 1, 0);
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads_)
    for (int64_t k = 0; k < n; ++k) first_connection_[size_t(k) + 1] = connect_sample(k, 0, false, Sampler());
    for (int64_t k = 0; k < n; ++k) first_connection_[size_t(k) + 1] += first_connection_[size_t(k)];
    const size_t total = size_t(first_connection_.back());
    connections_.assign(total, Connection{});
    shadow_.open(total);
    connections_made_ += total;
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads_)
    for (int64_t k = 0; k < n; ++k) {
        const Sampler rng(stream_key(seed_ ^ stream_tag::kBdptConnections, uint64_t(iteration), uint64_t(k)));
        connect_sample(k, first_connection_[size_t(k)], true, rng);
    }
}

int BidirectionalPathTracing::connect_sample(int64_t k, int64_t first, bool fill, Sampler rng) {
    const Scene &scene = *scene_;
    const Camera &cam = scene.camera;
    const Subpath light = light_subpath(k), camera = camera_subpath(k);
    const int64_t pixels = int64_t(cam.width) * cam.height, pixel = k % pixels;
    int64_t j = first;
    // Opens connection j (slot j of the shadow queue): its strategy, pixel, value and weight.
    auto open = [&](int s, int t, int64_t to_pixel, const RGB &value, double rest) -> Connection & {
        Connection &c = connections_[size_t(j)];
        c.s = int16_t(s);
        c.t = int16_t(t);
        c.pixel = to_pixel;
        c.value = value;
        c.mis_rest = rest;
        shadow_[size_t(j)].live = false;
        return c;
    };
    // Aims connection j's shadow ray from vertex v at `target`.
    auto aim = [&](Connection &c, const PathVertex &v, const Vec3 &target, double target_eps, Sampler ray_rng) {
        ShadowRay &r = shadow_[size_t(j)];
        if (is_black(c.value)) return;
        const Vec3 dir = normalize(target - v.pos);
        r.dir = dir;
        r.to_infinity = false;
        r.target = target;
        r.target_eps = target_eps;
        r.restart_at(shadow_start(scene, v, dir, r.medium));
        r.receiver = j;
        r.contribution = c.value;
        r.tau = 0;
        r.rng = ray_rng;
        r.live = true;
        c.needs_ray = true;
    };

    for (int t = 2; t <= camera.count; ++t) {
        const PathVertex &z = *camera.vertices[t - 1];
        // s = 0: the camera subpath found an emitter (lit from its front side).
        if (z.kind == VertexKind::Surface && scene.triangles[z.triangle].emitter >= 0 && depth_.allows(t - 2)) {
            const RGB Le = scene.emitted(z.triangle, -z.wi);
            if (!is_black(Le)) {
                if (fill) {
                    Connection &c = open(0, t, pixel, z.throughput * Le, mis_rest(nullptr, 0, camera.vertices, t, nullptr));
                    c.arrived = true;
                }
                ++j;
            }
        }
        if (!connectible(scene, z)) continue;
        // s = 1: next-event estimation from z, a fresh sample of a light.
        if (depth_.allows(t - 1)) {
            if (fill) {
                Sampler nee = rng.split(0x10000u + uint64_t(t));
                const LightSample ls = scene.sample_light(z.pos, nee);
                Connection &c = open(1, t, pixel, RGB(0.0), 0.0);
                if (ls.valid) {
                    PathVertex y;  // the light's vertex, as a light subpath would record it
                    y.kind = VertexKind::Emission;
                    y.light = int16_t(ls.light);
                    y.triangle = ls.triangle;
                    // A directional light's vertex lies anywhere up its direction.
                    y.pos = std::isfinite(ls.dist) ? ls.point : z.pos + ls.wi;
                    double pdf_pos;
                    emitter_density_vertex(scene, ls.light, y.pos, ls.triangle, pdf_pos);
                    y.pdf_fwd = pdf_pos;
                    y.delta = ls.delta;
                    c.value = z.throughput * scattering(scene, z, ls.wi) * ls.value;
                    const PathVertex *light_prefix[1] = {&y};
                    c.mis_rest = mis_rest(light_prefix, 1, camera.vertices, t, &y);
                    ShadowRay &r = shadow_[size_t(j)];
                    if (!is_black(c.value)) {
                        r.dir = ls.wi;
                        r.to_infinity = !std::isfinite(ls.dist);
                        r.target = r.to_infinity ? Vec3() : ls.point;
                        r.target_eps = r.to_infinity ? 0 : scene.light_clearance(ls.point);
                        r.restart_at(shadow_start(scene, z, ls.wi, r.medium));
                        r.receiver = j;
                        r.contribution = c.value;
                        r.tau = 0;
                        r.rng = nee.fork();
                        r.live = true;
                        c.needs_ray = true;
                    }
                }
            }
            ++j;
        }
        // s >= 2: z joined to each vertex of the light subpath.
        for (int s = 2; s <= light.count && made(s, t) && depth_.allows(s + t - 2); ++s) {
            const PathVertex &y = *light.vertices[s - 1];
            if (!connectible(scene, y)) continue;
            if (fill) {
                const Vec3 d = y.pos - z.pos;
                const double d2 = dot(d, d);
                RGB value(0.0);
                if (d2 > 0) {
                    const Vec3 dir = d / std::sqrt(d2);
                    value = y.throughput * scattering(scene, y, -dir) * scattering(scene, z, dir) * z.throughput / d2;
                }
                Connection &c = open(s, t, pixel, value, 0.0);
                if (!is_black(value)) {
                    c.mis_rest = mis_rest(light.vertices, s, camera.vertices, t, nullptr);
                    aim(c, z, y.pos, stop_short(scene, y), rng.split((uint64_t(s) << 20) ^ uint64_t(t)));
                }
            }
            ++j;
        }
    }
    // t = 1: the light subpath's vertices joined to the camera (light tracing, lt.h): an area
    // light's own vertex (point, spot and directional lights cannot be seen by a pinhole), then
    // every connectible vertex.
    if (camera.count >= 1) {
        for (int s = 1; s <= light.count && depth_.allows(s - 1); ++s) {
            const PathVertex &y = *light.vertices[s - 1];
            const bool seen = s == 1 ? y.kind == VertexKind::Emission && y.triangle >= 0 : connectible(scene, y);
            if (!seen) continue;
            if (fill) {
                const CameraConnection cc = connect_to_camera(cam, y.pos);
                RGB value(0.0);
                if (cc.valid) {
                    const RGB f = s == 1 ? RGB(std::max(0.0, dot(scene.triangles[y.triangle].n, cc.to_camera)))
                                         : scattering(scene, y, cc.to_camera);
                    value = y.throughput * f * (cc.importance / double(pixels));
                }
                Connection &c = open(s, 1, cc.valid ? cc.pixel : -1, value, 0.0);
                if (!is_black(value)) {
                    c.mis_rest = mis_rest(light.vertices, s, camera.vertices, 1, nullptr);
                    // Stops an offset short of the camera (lt.h: a boundary through the camera).
                    aim(c, y, cam.origin, scene.offset_length(cam.origin), rng.split((uint64_t(s) << 20) ^ 1u));
                }
            }
            ++j;
        }
    }
    return int(j - first);
}

namespace {

struct MisVertex {
    double fwd = 0, rev = 0;
    bool delta = false;
};

}  // namespace

double bdpt_mis_rest(const Scene &scene, int max_connect, const PathVertex *const *light, int s,
                     const PathVertex *const *camera, int t, const PathVertex *fresh_light) {
    auto made = [&](int ls, int lt) { return bdpt_made(max_connect, ls, lt); };
    thread_local std::vector<MisVertex> L, C;
    L.assign(size_t(s), MisVertex{});
    C.assign(size_t(t), MisVertex{});
    for (int i = 0; i < s; ++i) {
        const PathVertex &v = i == 0 && fresh_light ? *fresh_light : *light[i];
        L[size_t(i)] = {v.pdf_fwd, v.pdf_rev, i > 0 && v.delta};  // a light's delta is no BSDF's
    }
    const bool delta_light = s > 0 && (fresh_light ? fresh_light->delta : light[0]->delta);
    for (int i = 0; i < t; ++i) C[size_t(i)] = {camera[i]->pdf_fwd, camera[i]->pdf_rev, camera[i]->delta};
    MediumStats lookups;  // the extinction at medium vertices: deterministic, not counted
    // The densities the connection changes, its own edge's flight left out (bdpt.h).
    if (s == 0) {
        // The camera subpath's last vertex is a light's: as a light subpath would sample it.
        const PathVertex &z = *camera[t - 1];
        double pdf_pos;
        const int light_index = scene.light_of_emitter(scene.triangles[z.triangle].emitter);
        const DensityVertex e = emitter_density_vertex(scene, light_index, z.pos, z.triangle, pdf_pos);
        C[size_t(t) - 1].rev = pdf_pos;
        if (t >= 3)
            C[size_t(t) - 2].rev = vertex_density(scene, e, Vec3(0.0), density_vertex(scene, *camera[t - 2], lookups),
                                                  z.tau_in);
        C[size_t(t) - 1].delta = false;
    } else if (t == 1) {
        const DensityVertex y = density_vertex(scene, *light[s - 1], lookups);
        const DensityVertex eye = density_vertex(scene, *camera[0], lookups);
        L[size_t(s) - 1].rev = vertex_density(scene, eye, Vec3(0.0), y, 0.0);
        if (s >= 2)
            L[size_t(s) - 2].rev = vertex_density(scene, y, normalize(eye.pos - y.pos),
                                                  density_vertex(scene, *light[s - 2], lookups), y.tau_in);
        L[size_t(s) - 1].delta = false;
    } else {
        const DensityVertex y = density_vertex(scene, s == 1 && fresh_light ? *fresh_light : *light[s - 1], lookups);
        const DensityVertex z = density_vertex(scene, *camera[t - 1], lookups);
        C[size_t(t) - 1].rev = vertex_density(scene, y, y.wi, z, 0.0);
        L[size_t(s) - 1].rev = vertex_density(scene, z, z.wi, y, 0.0);
        if (t >= 3)
            C[size_t(t) - 2].rev = vertex_density(scene, z, normalize(y.pos - z.pos),
                                                  density_vertex(scene, *camera[t - 2], lookups), z.tau_in);
        if (s >= 2)
            L[size_t(s) - 2].rev = vertex_density(scene, y, normalize(z.pos - y.pos),
                                                  density_vertex(scene, *light[s - 2], lookups), y.tau_in);
        C[size_t(t) - 1].delta = L[size_t(s) - 1].delta = false;
    }
    // The power heuristic's sum, outwards from the connection (pbrt-v3's MISWeight).
    auto remap = [](double p) { return p != 0 ? p : 1.0; };
    const int n = s + t;
    double sum = 0, ratio = 1;
    for (int i = t - 1; i > 0; --i) {  // the connection moved to (n - i, i)
        ratio *= remap(C[size_t(i)].rev) / remap(C[size_t(i)].fwd);
        if (!C[size_t(i)].delta && !C[size_t(i) - 1].delta && made(n - i, i)) sum += ratio * ratio;
    }
    ratio = 1;
    for (int i = s - 1; i >= 0; --i) {  // the connection moved to (i, n - i)
        ratio *= remap(L[size_t(i)].rev) / remap(L[size_t(i)].fwd);
        const bool before_delta = i > 0 ? L[size_t(i) - 1].delta : delta_light;
        if (!L[size_t(i)].delta && !before_delta && made(i, n - i)) sum += ratio * ratio;
    }
    return sum;
}

void BidirectionalPathTracing::resolve_shadows(const Hits &hits) {
    shadow_.resolve(*scene_, hits, threads_, stats_, [&](int64_t j, const RGB &value, double tau) {
        Connection &c = connections_[size_t(j)];  // one ray per connection: no race
        c.value = value;
        c.tau = tau;
        c.arrived = true;
    });
}

void BidirectionalPathTracing::end() {
    const int w = film_.width, h = film_.height;
    for (const Connection &c : connections_) {
        if (!c.arrived || c.pixel < 0) continue;
        // The other strategies' ratios each hold the connection's flight once (bdpt.h).
        const double rest = c.needs_ray ? c.mis_rest * std::exp(-2 * c.tau) : c.mis_rest;
        const double weight = std::isinf(c.mis_rest) ? 0.0 : 1 / (1 + rest);
        film_.add(c.pixel, c.value * weight);
        if (strategy_images_) {
            auto it = strategies_.try_emplace({c.s, c.t}, StrategyImages{Film(w, h), Film(w, h)}).first;
            it->second.weighted.add(c.pixel, c.value * weight);
            it->second.unweighted.add(c.pixel, c.value);
        }
    }
    film_.samples_per_pixel += uint64_t(spp_);
    // Every strategy image counts every iteration's samples, whether it had a path or not.
    for (auto &[key, images] : strategies_) {
        images.weighted.samples_per_pixel = film_.samples_per_pixel;
        images.unweighted.samples_per_pixel = film_.samples_per_pixel;
    }
    connections_.clear();
    shadow_.clear();
}

std::vector<std::tuple<int, int, double>> bdpt_path_weights(const Scene &scene, int max_connect,
                                                            const std::vector<PathVertex> &path,
                                                            const std::vector<double> &edge_tau) {
    const int n = int(path.size());
    if (n < 2 || int(edge_tau.size()) != n - 1) throw std::invalid_argument("bdpt_path_weights: n vertices, n - 1 edges");
    // Each vertex as the light side sees it (wi towards the light end) and as the camera side
    // does (wi towards the camera end), with the density each side samples it with.
    std::vector<PathVertex> from_light(path), from_camera(path);
    MediumStats lookups;
    for (int i = 0; i < n; ++i) {
        if (i > 0) {
            from_light[i].wi = normalize(path[i - 1].pos - path[i].pos);
            from_light[i].tau_in = edge_tau[i - 1];
        }
        if (i < n - 1) {
            from_camera[i].wi = normalize(path[i + 1].pos - path[i].pos);
            from_camera[i].tau_in = edge_tau[i];
        }
    }
    // A directional light's vertex has no distance to its next: as subpaths.h records it.
    std::vector<double> light_density(n, 0.0), camera_density(n, 0.0);
    double pdf_pos = 0;
    emitter_density_vertex(scene, path[0].light, path[0].pos, path[0].triangle, pdf_pos);
    light_density[0] = pdf_pos;
    for (int i = 1; i < n; ++i) {
        const DensityVertex a = density_vertex(scene, from_light[i - 1], lookups);
        light_density[i] = vertex_density(scene, a, a.wi, density_vertex(scene, from_light[i], lookups), edge_tau[i - 1]);
    }
    camera_density[n - 1] = 1;
    for (int i = n - 2; i >= 0; --i) {
        const DensityVertex a = density_vertex(scene, from_camera[i + 1], lookups);
        camera_density[i] = vertex_density(scene, a, a.wi, density_vertex(scene, from_camera[i], lookups), edge_tau[i]);
    }
    for (int i = 0; i < n; ++i) {
        from_light[i].pdf_fwd = from_camera[i].pdf_rev = light_density[i];
        from_light[i].pdf_rev = from_camera[i].pdf_fwd = camera_density[i];
    }
    std::vector<std::tuple<int, int, double>> out;
    for (int s = 0; s < n; ++s) {
        const int t = n - s;
        std::vector<const PathVertex *> light, camera;
        for (int i = 0; i < s; ++i) light.push_back(&from_light[i]);
        for (int j = 0; j < t; ++j) camera.push_back(&from_camera[n - 1 - j]);
        // Can strategy (s, t) sample this path?
        const PathVertex &camera_end = from_camera[s];
        bool possible;
        if (s == 0) {
            possible = camera_end.kind == VertexKind::Emission && camera_end.triangle >= 0;
        } else if (t == 1) {
            possible = s == 1 ? path[0].triangle >= 0 : connectible(scene, path[s - 1]);
        } else {
            possible = (s == 1 || connectible(scene, path[s - 1])) && connectible(scene, camera_end) &&
                       bdpt_made(max_connect, s, t);
        }
        if (!possible) continue;
        double rest = bdpt_mis_rest(scene, max_connect, light.data(), s, camera.data(), t, nullptr);
        if (s > 0) rest *= std::exp(-2 * edge_tau[s - 1]);  // the connection's own flight
        out.emplace_back(s, t, std::isinf(rest) ? 0.0 : 1 / (1 + rest));
    }
    return out;
}

}  // namespace pgi
