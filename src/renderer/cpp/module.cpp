// Python bindings of the native core: scene construction, the wavefront
// kernels of each method, and probes of the sampling routines for tests.
#include "bindings.h"
#include "subpaths.h"
#include "surface_photons.h"

namespace nb = nanobind;
using namespace nb::literals;
using namespace pgi;
using namespace pgi::bind;

// The kinds a scene file names, bound under the names it uses: Python looks them up by
// name, and a binding that takes one refuses any value that is none of them.
static void add_kinds(nb::module_ &m) {
    nb::enum_<MaterialType>(m, "MaterialType")
        .value("diffuse", MaterialType::Diffuse)
        .value("mirror", MaterialType::Mirror)
        .value("dielectric", MaterialType::Dielectric)
        .value("null", MaterialType::Null);
    nb::enum_<PhaseType>(m, "PhaseType")
        .value("isotropic", PhaseType::Isotropic)
        .value("hg", PhaseType::HenyeyGreenstein)
        .value("rayleigh", PhaseType::Rayleigh)
        .value("tabulated", PhaseType::Tabulated);
    nb::enum_<Roulette>(m, "Roulette")
        .value("throughput", Roulette::Throughput)
        .value("mitsuba", Roulette::Mitsuba);
    nb::enum_<Estimator>(m, "Estimator")
        .value("delta", Estimator::Delta)
        .value("ratio", Estimator::Ratio)
        .value("residual", Estimator::Residual)
        .value("raymarch", Estimator::RayMarch);
}

static void add_scene(nb::module_ &m) {
    nb::class_<Scene>(m, "Scene")
        .def(nb::new_([]() { return std::make_shared<Scene>(); }))
        .def("set_triangles",
             [](Scene &s, Array<double> verts, Array<int32_t> material, Array<int32_t> emitter,
                Array<int32_t> interior, Array<int32_t> exterior, Array<uint8_t> transition) {
                 if (verts.ndim() != 3 || verts.shape(1) != 3 || verts.shape(2) != 3)
                     throw std::invalid_argument("vertices must be (T, 3, 3) float64");
                 size_t n = verts.shape(0);
                 for (auto *a : {&material, &emitter, &interior, &exterior}) check_len(a->shape(0), n, "triangle attribute");
                 check_len(transition.shape(0), n, "triangle attribute");
                 s.triangles.resize(n);
                 const double *v = verts.data();
                 for (size_t i = 0; i < n; ++i) {
                     Triangle &t = s.triangles[i];
                     Vec3 a(v[9 * i], v[9 * i + 1], v[9 * i + 2]), b(v[9 * i + 3], v[9 * i + 4], v[9 * i + 5]),
                         c(v[9 * i + 6], v[9 * i + 7], v[9 * i + 8]);
                     t.p0 = a;
                     t.e1 = b - a;
                     t.e2 = c - a;
                     Vec3 nrm = cross(t.e1, t.e2);
                     double len = length(nrm);
                     if (!(len > 0)) throw std::invalid_argument("degenerate triangle passed to the core");
                     t.n = nrm / len;
                     t.area = 0.5 * len;
                     t.material = material.data()[i];
                     t.emitter = emitter.data()[i];
                     t.interior = interior.data()[i];
                     t.exterior = exterior.data()[i];
                     t.transition = transition.data()[i] != 0;
                 }
             }, "vertices"_a, "material"_a, "emitter"_a, "interior"_a, "exterior"_a, "transition"_a)
        .def("add_material",
             [](Scene &s, MaterialType type, V3 reflectance, double ior) {
                 s.materials.push_back(Material{type, vec(reflectance), ior});
                 return int(s.materials.size() - 1);
             }, "type"_a, "reflectance"_a, "ior"_a)
        .def("add_homogeneous_medium",
             [](Scene &s, V3 sigma_t, V3 albedo, PhaseType phase, double g) {
                 Medium m;
                 m.type = MediumType::Homogeneous;
                 m.sigma_t = vec(sigma_t);
                 m.albedo = vec(albedo);
                 m.phase = Phase{phase, g};
                 s.media.push_back(std::move(m));
                 return int(s.media.size() - 1);
             }, "sigma_t"_a, "albedo"_a, "phase"_a, "g"_a)
        .def("add_grid_medium",
             [](Scene &s, Array<float> density_zyx, Array<double> world_to_local, double sigma, V3 albedo,
                PhaseType phase, double g, int majorant_cell) {
                 if (density_zyx.ndim() != 3) throw std::invalid_argument("density must be 3D (z, y, x)");
                 if (world_to_local.ndim() != 2 || world_to_local.shape(0) < 3 || world_to_local.shape(1) != 4)
                     throw std::invalid_argument("world_to_local must be (3|4, 4)");
                 Medium m;
                 m.type = MediumType::Grid;
                 m.grid_sigma = sigma;
                 m.albedo = vec(albedo);
                 m.phase = Phase{phase, g};
                 DensityGrid &G = m.grid;
                 G.nz = int(density_zyx.shape(0));
                 G.ny = int(density_zyx.shape(1));
                 G.nx = int(density_zyx.shape(2));
                 G.values.assign(density_zyx.data(), density_zyx.data() + density_zyx.size());
                 for (int r = 0; r < 3; ++r)
                     for (int c = 0; c < 4; ++c) G.world_to_local[r][c] = world_to_local.data()[4 * r + c];
                 G.build_majorants(majorant_cell);
                 s.media.push_back(std::move(m));
                 return int(s.media.size() - 1);
             }, "density_zyx"_a, "world_to_local"_a, "sigma"_a, "albedo"_a, "phase"_a, "g"_a,
             "majorant_cell"_a)
        .def("add_area_light",
             [](Scene &s, V3 radiance, Array<int32_t> triangles) {
                 AreaEmitter e;
                 e.radiance = vec(radiance);
                 e.triangles.assign(triangles.data(), triangles.data() + triangles.size());
                 s.area_emitters.push_back(std::move(e));
                 Light l;
                 l.type = LightType::Area;
                 l.emitter = int(s.area_emitters.size() - 1);
                 s.lights.push_back(l);
                 return l.emitter;  // the emitter's index, which its triangles name (not the light's)
             }, "radiance"_a, "triangles"_a)
        .def("add_point_light",
             [](Scene &s, V3 position, V3 intensity) {
                 Light l;
                 l.type = LightType::Point;
                 l.position = vec(position);
                 l.intensity = vec(intensity);
                 s.lights.push_back(l);
                 return int(s.lights.size() - 1);  // the light's index
             }, "position"_a, "intensity"_a)
        .def("add_spot_light",
             [](Scene &s, V3 position, V3 direction, V3 intensity, double cutoff, double beam_width) {
                 Light l;
                 l.type = LightType::Spot;
                 l.position = vec(position);
                 l.direction = normalize(vec(direction));
                 l.intensity = vec(intensity);
                 l.cutoff = cutoff;
                 l.beam_width = std::min(beam_width, cutoff);
                 l.cos_cutoff = std::cos(cutoff);
                 l.cos_beam = std::cos(l.beam_width);
                 s.lights.push_back(l);
                 return int(s.lights.size() - 1);  // the light's index
             }, "position"_a, "direction"_a, "intensity"_a, "cutoff"_a, "beam_width"_a)
        .def("add_directional_light",
             [](Scene &s, V3 direction, V3 irradiance) {
                 Light l;
                 l.type = LightType::Directional;
                 l.direction = normalize(vec(direction));
                 l.intensity = vec(irradiance);
                 s.lights.push_back(l);
                 return int(s.lights.size() - 1);  // the light's index
             }, "direction"_a, "irradiance"_a)
        .def("set_camera",
             [](Scene &s, V3 origin, V3 forward, V3 right, V3 up, int width, int height, int medium) {
                 s.camera = Camera{vec(origin), vec(forward), vec(right), vec(up), width, height, medium};
             }, "origin"_a, "forward"_a, "right"_a, "up"_a, "width"_a, "height"_a, "medium"_a)
        .def_rw("roulette", &Scene::roulette, "The Russian roulette rule of every path (scene.h).")
        .def("finalize", &Scene::finalize)
        .def_prop_ro("triangle_count", [](const Scene &s) { return s.triangles.size(); })
        .def_prop_ro("ray_epsilon", [](const Scene &s) { return s.ray_epsilon; })
        .def_prop_ro("scene_radius", [](const Scene &s) { return s.scene_radius; })
        .def_prop_ro("light_count", [](const Scene &s) { return s.lights.size(); })
        .def("directional_disk",
             [](const Scene &s, V3 direction) {
                 const Scene::Disk d = s.directional_disk(normalize(vec(direction)));
                 return std::make_tuple(std::array<double, 3>{d.centre.x, d.centre.y, d.centre.z}, d.radius);
             }, "direction"_a)
        .def_prop_ro("scene_center",
                     [](const Scene &s) { return std::array<double, 3>{s.scene_center.x, s.scene_center.y, s.scene_center.z}; })
        .def("set_emission_media",
             [](Scene &s, Array<int32_t> per_triangle, Array<int32_t> per_light) {
                 s.set_emission_media({per_triangle.data(), per_triangle.data() + per_triangle.size()},
                                      {per_light.data(), per_light.data() + per_light.size()});
             }, "per_triangle"_a, "per_light"_a)
        .def("emission_media",
             [](const Scene &s) {
                 std::vector<int32_t> per_triangle(s.triangles.size()), per_light(s.lights.size());
                 for (size_t i = 0; i < per_triangle.size(); ++i) per_triangle[i] = s.triangle_emission_medium(int(i));
                 for (size_t i = 0; i < per_light.size(); ++i) per_light[i] = s.light_emission_medium(int(i));
                 const size_t triangles = per_triangle.size(), lights = per_light.size();
                 return std::make_tuple(to_numpy(std::move(per_triangle), {triangles}),
                                        to_numpy(std::move(per_light), {lights}));
             })
        // The medium where the straight walk from the camera to each of `points` (n, 3) ends.
        .def("walk_media",
             [](const Scene &s, Array<double> points) {
                 if (points.ndim() != 2 || points.shape(1) != 3) throw std::invalid_argument("points must be (n, 3) float64");
                 const size_t n = points.shape(0);
                 std::vector<int32_t> media(n);
                 const double *p = points.data();
                 // Each walk visits every boundary triangle: many points (a large emitting mesh)
                 // are shared among the threads.
#pragma omp parallel for schedule(dynamic, 16)
                 for (int64_t i = 0; i < int64_t(n); ++i)
                     media[size_t(i)] = s.walk_medium(Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]));
                 return to_numpy(std::move(media), {n});
             }, "points"_a)
        // Probes for tests: estimators evaluated in isolation.
        .def("transmittance",
             [](const Scene &s, int medium, V3 origin, V3 direction, double tmax, uint64_t seed, int64_t n) {
                 MediumStats st;
                 RGB sum(0.0);
                 Vec3 o = vec(origin), d = normalize(vec(direction));
                 for (int64_t i = 0; i < n; ++i) {
                     Sampler rng(stream_key(seed, uint64_t(i), 0x7472));
                     sum += transmittance(s.media.at(medium), o, d, tmax, rng, st);
                 }
                 RGB mean_tr = sum / double(std::max<int64_t>(1, n));
                 return std::make_tuple(V3{mean_tr.x, mean_tr.y, mean_tr.z}, st.density_lookups);
             }, "medium"_a, "origin"_a, "direction"_a, "tmax"_a, "seed"_a, "n"_a)
        .def("free_flight",
             [](const Scene &s, int medium, V3 origin, V3 direction, double tmax, uint64_t seed, int64_t n) {
                 // Returns (t or inf, weight rgb) per sample: for testing distance sampling.
                 std::vector<double> t(n), w(3 * n);
                 MediumStats st;
                 Vec3 o = vec(origin), d = normalize(vec(direction));
                 for (int64_t i = 0; i < n; ++i) {
                     Sampler rng(stream_key(seed, uint64_t(i), 0x6666));
                     SpectralMis spectral{hero_channel(rng)};  // a path's first flight
                     FreeFlight f = sample_free_flight(s.media.at(medium), o, d, tmax, rng, st, spectral);
                     t[i] = f.scattered ? f.t : kInf;
                     w[3 * i] = f.weight.x; w[3 * i + 1] = f.weight.y; w[3 * i + 2] = f.weight.z;
                 }
                 return std::make_tuple(to_numpy(std::move(t), {size_t(n)}), to_numpy(std::move(w), {size_t(n), 3}));
             }, "medium"_a, "origin"_a, "direction"_a, "tmax"_a, "seed"_a, "n"_a)
        // The deterministic stand-in optical depth that path densities use (medium.h).
        .def("flight_depth",
             [](const Scene &s, int medium, V3 origin, V3 direction, double length) {
                 return flight_depth(s.media.at(medium), vec(origin), normalize(vec(direction)), length);
             }, "medium"_a, "origin"_a, "direction"_a, "length"_a)
        .def("density",
             [](const Scene &s, int medium, Array<double> points) {
                 size_t n = points.shape(0);
                 std::vector<double> out(n);
                 const Medium &m = s.media.at(medium);
                 for (size_t i = 0; i < n; ++i) {
                     Vec3 p(points.data()[3 * i], points.data()[3 * i + 1], points.data()[3 * i + 2]);
                     out[i] = m.grid.density_local(m.grid.to_local(p));
                 }
                 return to_numpy(std::move(out), {n});
             }, "medium"_a, "points"_a)
        // Surface density estimation's sum (reflected_photon_power) at x on triangle `tri`,
        // seen from wo, over the photons given (positions, triangles, incoming directions,
        // powers), every depth counted: which photons belong to the surface.
        .def("surface_photon_power",
             [](const Scene &s, int tri, V3 x, V3 wo, double radius, Array<double> pos,
                Array<int32_t> triangle, Array<double> wi, Array<double> power) {
                 size_t n = pos.shape(0);
                 if (triangle.shape(0) != n || wi.shape(0) != n || power.shape(0) != n)
                     throw std::invalid_argument("surface_photon_power: photon arrays differ in length");
                 auto valid = [&](int32_t t) { return t >= 0 && size_t(t) < s.triangles.size(); };
                 if (!valid(tri) || !std::all_of(triangle.data(), triangle.data() + n, valid))
                     throw std::invalid_argument("surface_photon_power: no such triangle");
                 std::vector<PathVertex> photons(n);
                 std::vector<Vec3> points(n);
                 for (size_t i = 0; i < n; ++i) {
                     const double *p = pos.data() + 3 * i, *w = wi.data() + 3 * i, *f = power.data() + 3 * i;
                     photons[i].pos = points[i] = Vec3(p[0], p[1], p[2]);
                     photons[i].wi = normalize(Vec3(w[0], w[1], w[2]));
                     photons[i].throughput = RGB(f[0], f[1], f[2]);
                     photons[i].triangle = triangle.data()[i];
                 }
                 PointTree tree;
                 tree.build(points);
                 RGB sum = reflected_photon_power(s, tree, photons, tri, vec(x), normalize(vec(wo)), radius,
                                                  [](const PathVertex &) { return true; });
                 return V3{sum.x, sum.y, sum.z};
             }, "tri"_a, "x"_a, "wo"_a, "radius"_a, "pos"_a, "triangle"_a, "wi"_a, "power"_a);
}

static void add_sampling_probes(nb::module_ &m) {
    m.def("power_heuristic", &power_heuristic, "pdf_a"_a, "pdf_b"_a);
    // The camera ray direction through each film point (fx, fy) in pixels, (0, 0) top-left.
    m.def("camera_directions",
          [](const Scene &s, Array<double> film_points) {
              size_t n = film_points.shape(0);
              std::vector<double> out(3 * n);
              for (size_t i = 0; i < n; ++i) {
                  Vec3 d = s.camera.direction(film_points.data()[2 * i], film_points.data()[2 * i + 1]);
                  for (int a = 0; a < 3; ++a) out[3 * i + a] = d[a];
              }
              return to_numpy(std::move(out), {n, 3});
          }, "scene"_a, "film_points"_a);
    // Samples (n, 3) added to an n x 1 film as every method adds them: the image (one
    // sample per pixel) and the count of non-finite samples the film dropped.
    m.def("film_add_samples",
          [](Array<double> samples) {
              size_t n = samples.shape(0);
              Film film(int(n), 1);
              for (size_t i = 0; i < n; ++i) {
                  const double *v = samples.data() + 3 * i;
                  film.add(int64_t(i), RGB(v[0], v[1], v[2]));
              }
              film.samples_per_pixel = 1;
              return std::make_tuple(film_image(film), film.nonfinite);
          }, "samples"_a);
    // Each takes uniform numbers and returns what the renderer would sample.
    m.def("sample_bsdf",
          [](MaterialType type, V3 reflectance, double ior, V3 normal, V3 wo, Array<double> u) {
              Material mat{type, vec(reflectance), ior};
              size_t n = u.shape(0);
              std::vector<double> wi(3 * n), weight(3 * n), pdf(n);
              std::vector<uint8_t> valid(n), delta(n);
              Vec3 nn = normalize(vec(normal)), w = normalize(vec(wo));
              for (size_t i = 0; i < n; ++i) {
                  const double *ui = u.data() + 3 * i;
                  BsdfSample s = bsdf_sample(mat, nn, w, ui[0], ui[1], ui[2]);
                  for (int a = 0; a < 3; ++a) {
                      wi[3 * i + a] = s.wi[a];
                      weight[3 * i + a] = s.weight[a];
                  }
                  pdf[i] = s.pdf;
                  valid[i] = s.valid;
                  delta[i] = s.delta;
              }
              return std::make_tuple(to_numpy(std::move(wi), {n, 3}), to_numpy(std::move(weight), {n, 3}),
                                     to_numpy(std::move(pdf), {n}), to_numpy(std::move(valid), {n}),
                                     to_numpy(std::move(delta), {n}));
          }, "type"_a, "reflectance"_a, "ior"_a, "normal"_a, "wo"_a, "u"_a);
    m.def("eval_bsdf",
          [](MaterialType type, V3 reflectance, double ior, V3 normal, V3 wo, Array<double> wi) {
              Material mat{type, vec(reflectance), ior};
              size_t n = wi.shape(0);
              std::vector<double> f(3 * n), pdf(n);
              Vec3 nn = normalize(vec(normal)), w = normalize(vec(wo));
              for (size_t i = 0; i < n; ++i) {
                  Vec3 d(wi.data()[3 * i], wi.data()[3 * i + 1], wi.data()[3 * i + 2]);
                  RGB v = bsdf_eval(mat, nn, w, d);
                  for (int a = 0; a < 3; ++a) f[3 * i + a] = v[a];
                  pdf[i] = bsdf_pdf(mat, nn, w, d);
              }
              return std::make_tuple(to_numpy(std::move(f), {n, 3}), to_numpy(std::move(pdf), {n}));
          }, "type"_a, "reflectance"_a, "ior"_a, "normal"_a, "wo"_a, "wi"_a);
    // The probability of picking each light (next-event estimation and emission alike).
    m.def("light_pmf",
          [](const Scene &s) {
              size_t n = s.light_selection.size();
              std::vector<double> pmf(n);
              for (size_t i = 0; i < n; ++i) pmf[i] = s.light_selection.pmf(i);
              return to_numpy(std::move(pmf), {n});
          }, "scene"_a);
    // Next-event light sampling from a point: u is (n, 4) uniforms (see Scene::sample_light).
    m.def("sample_light",
          [](const Scene &s, V3 from, Array<double> u) {
              size_t n = u.shape(0);
              std::vector<double> point(3 * n), wi(3 * n), value(3 * n), pdf(n);
              std::vector<int32_t> light(n), triangle(n);
              std::vector<uint8_t> valid(n), delta(n);
              const Vec3 p = vec(from);
              for (size_t i = 0; i < n; ++i) {
                  const double *ui = u.data() + 4 * i;
                  LightSample ls = s.sample_light(p, ui[0], ui[1], ui[2], ui[3]);
                  for (int a = 0; a < 3; ++a) {
                      point[3 * i + a] = ls.point[a];
                      wi[3 * i + a] = ls.wi[a];
                      value[3 * i + a] = ls.value[a];
                  }
                  pdf[i] = ls.pdf;
                  light[i] = ls.light;
                  triangle[i] = ls.triangle;
                  valid[i] = ls.valid;
                  delta[i] = ls.delta;
              }
              return nb::make_tuple(to_numpy(std::move(point), {n, 3}), to_numpy(std::move(wi), {n, 3}),
                                    to_numpy(std::move(value), {n, 3}), to_numpy(std::move(pdf), {n}),
                                    to_numpy(std::move(light), {n}), to_numpy(std::move(triangle), {n}),
                                    to_numpy(std::move(valid), {n}), to_numpy(std::move(delta), {n}));
          }, "scene"_a, "from_point"_a, "u"_a);
    // The solid-angle pdf MIS uses for a hit on emissive triangle tri[i] at hit[i] from a point.
    m.def("area_light_pdf",
          [](const Scene &s, V3 from, Array<int32_t> tri, Array<double> hit) {
              size_t n = tri.shape(0);
              check_len(hit.shape(0), n, "hit points");
              std::vector<double> pdf(n);
              const Vec3 p = vec(from);
              for (size_t i = 0; i < n; ++i) {
                  const double *h = hit.data() + 3 * i;
                  pdf[i] = s.area_light_pdf(tri.data()[i], p, Vec3(h[0], h[1], h[2]));
              }
              return to_numpy(std::move(pdf), {n});
          }, "scene"_a, "from_point"_a, "triangle"_a, "hit"_a);
    // Light-path emission: u is (n, 6) uniforms (see sample_emission in subpaths.h).
    m.def("sample_emission",
          [](const Scene &s, Array<double> u) {
              size_t n = u.shape(0);
              std::vector<double> pos(3 * n), dir(3 * n), power(3 * n), vertex_power(3 * n);
              std::vector<int32_t> light(n), triangle(n);
              std::vector<uint8_t> has_direction(n);
              for (size_t i = 0; i < n; ++i) {
                  EmissionSample e = sample_emission(s, u.data() + 6 * i);
                  for (int a = 0; a < 3; ++a) {
                      pos[3 * i + a] = e.pos[a];
                      dir[3 * i + a] = e.dir[a];
                      power[3 * i + a] = e.power[a];
                      vertex_power[3 * i + a] = e.vertex_power[a];
                  }
                  light[i] = e.light;
                  triangle[i] = e.triangle;
                  has_direction[i] = e.has_direction;
              }
              return nb::make_tuple(to_numpy(std::move(pos), {n, 3}), to_numpy(std::move(dir), {n, 3}),
                                    to_numpy(std::move(power), {n, 3}), to_numpy(std::move(vertex_power), {n, 3}),
                                    to_numpy(std::move(light), {n}), to_numpy(std::move(triangle), {n}),
                                    to_numpy(std::move(has_direction), {n}));
          }, "scene"_a, "u"_a);
    // The warps of sampling.h that emission uses (spot cone, directional disk): u is (n, 2)
    // uniforms; each returns the samples and the pdf the warp reports for them.
    m.def("sample_uniform_cone",
          [](V3 axis, double cos_cutoff, Array<double> u) {
              if (u.ndim() != 2 || u.shape(1) != 2) throw std::invalid_argument("u must be (n, 2)");
              size_t n = u.shape(0);
              std::vector<double> dir(3 * n), pdf(n);
              const Vec3 a = normalize(vec(axis));
              for (size_t i = 0; i < n; ++i) {
                  const double *ui = u.data() + 2 * i;
                  Vec3 d = square_to_uniform_cone(a, cos_cutoff, ui[0], ui[1]);
                  for (int k = 0; k < 3; ++k) dir[3 * i + k] = d[k];
                  pdf[i] = square_to_uniform_cone_pdf(cos_cutoff);
              }
              return std::make_tuple(to_numpy(std::move(dir), {n, 3}), to_numpy(std::move(pdf), {n}));
          }, "axis"_a, "cos_cutoff"_a, "u"_a);
    m.def("sample_uniform_disk",
          [](Array<double> u) {
              if (u.ndim() != 2 || u.shape(1) != 2) throw std::invalid_argument("u must be (n, 2)");
              size_t n = u.shape(0);
              std::vector<double> point(3 * n), pdf(n);
              for (size_t i = 0; i < n; ++i) {
                  const double *ui = u.data() + 2 * i;
                  Vec3 p = square_to_uniform_disk_concentric(ui[0], ui[1]);
                  for (int k = 0; k < 3; ++k) point[3 * i + k] = p[k];
                  pdf[i] = square_to_uniform_disk_concentric_pdf();
              }
              return std::make_tuple(to_numpy(std::move(point), {n, 3}), to_numpy(std::move(pdf), {n}));
          }, "u"_a);
    m.def("sample_phase",
          [](PhaseType type, double g, V3 wo, Array<double> u) {
              Phase ph{type, g};
              return probe_phase_sample(ph, wo, u);
          }, "type"_a, "g"_a, "wo"_a, "u"_a);
    m.def("eval_phase",
          [](PhaseType type, double g, V3 wo, Array<double> wi) {
              Phase ph{type, g};
              return probe_phase_eval(ph, wo, wi);
          }, "type"_a, "g"_a, "wo"_a, "wi"_a);
}

NB_MODULE(_core, m) {
    m.doc() = "pgi native core: scene, media, sampling and the wavefront kernels of each method";
    m.def("max_threads", []() { return omp_get_max_threads(); });
    // renderer.interrupts: a signal seen while a pass runs cuts its media tracking short.
    m.def("request_interrupt", []() { interrupt_flag().store(true); });
    m.def("clear_interrupt", []() { interrupt_flag().store(false); });
    add_kinds(m);
    add_scene(m);
    add_sampling_probes(m);
    // Each kernel's and probe family's own file (PGI_BINDING), in the order of their names.
    std::vector<std::pair<std::string, Binder>> all = binders();
    std::sort(all.begin(), all.end(), [](const auto &a, const auto &b) { return a.first < b.first; });
    for (const auto &[name, bind] : all) bind(m);
}
