// Bindings of the photon-mapping kernel (pm.h, shared by pm and sppm), the photon
// kd-tree (photon_map.h, exposed for tests) and the radius schedule.
#include "bindings.h"
#include "pm.h"
#include "radius_schedule.h"

namespace pgi::bind {

using namespace nb::literals;

namespace {

std::vector<Vec3> points_of(Array<double> pts) {
    if (pts.ndim() != 2 || pts.shape(1) != 3) throw std::invalid_argument("points must be (n, 3) float64");
    std::vector<Vec3> v(pts.shape(0));
    for (size_t i = 0; i < v.size(); ++i) v[i] = {pts.data()[3 * i], pts.data()[3 * i + 1], pts.data()[3 * i + 2]};
    return v;
}

}  // namespace

void bind_pm(nb::module_ &m) {
    nb::class_<PointTree>(m, "PointTree")
        .def("__init__",
             [](PointTree *t, Array<double> pts) {
                 new (t) PointTree();
                 t->build(points_of(pts));
             })
        .def_prop_ro("size", &PointTree::size)
        .def("query_sphere",
             [](const PointTree &t, V3 c, double r) {
                 std::vector<int64_t> out;
                 t.query_sphere(vec(c), r, [&](uint32_t i, double) { out.push_back(i); });
                 size_t n = out.size();
                 return to_numpy(std::move(out), {n});
             }, "center"_a, "radius"_a)
        .def("query_ray",
             [](const PointTree &t, V3 o, V3 d, double tmax, double r) {
                 std::vector<int64_t> out;
                 t.query_ray(vec(o), normalize(vec(d)), tmax, r, [&](uint32_t i, double, double) { out.push_back(i); });
                 size_t n = out.size();
                 return to_numpy(std::move(out), {n});
             }, "origin"_a, "direction"_a, "tmax"_a, "radius"_a);

    m.def("radius_schedule",
          [](double r1, double alpha, int dimension, int64_t iterations) {
              RadiusSchedule s(r1, alpha, dimension);
              std::vector<double> r(size_t(std::max<int64_t>(0, iterations)));
              for (size_t k = 0; k < r.size(); ++k) r[k] = s.radius(int64_t(k));
              size_t n = r.size();
              return to_numpy(std::move(r), {n});
          }, "initial"_a, "alpha"_a, "dimension"_a, "iterations"_a);
    m.def("radius_schedule_mse_slope",
          [](double alpha, int dimension, int bias_order) {
              if (bias_order != 1 && bias_order != 2) throw std::invalid_argument("bias order must be 1 or 2");
              return RadiusSchedule(1.0, alpha, dimension).mse_slope(bias_order);
          },
          "alpha"_a, "dimension"_a, "bias_order"_a = 2);

    nb::class_<PhotonGatherer>(m, "PhotonGatherer")
        .def(nb::init<std::shared_ptr<const Scene>, int, uint64_t, int, int>(), "scene"_a, "max_depth"_a, "seed"_a,
             "spp_per_iteration"_a, "threads"_a)
        .def_prop_ro("capacity", &PhotonGatherer::capacity)
        .def("build_maps",
             [](PhotonGatherer &g, const LightPathTracer &paths) {
                 released([&] { g.build_maps(paths); });
             })
        .def("begin_camera",
             [](PhotonGatherer &g, int64_t it, Array<float> o, Array<float> d, Array<float> t) {
                 RayBuffers b = ray_buffers(o, d, t);
                 return released([&] { return g.begin_camera(it, b); });
             }, "iteration"_a, "o"_a.noconvert(), "d"_a.noconvert(), "t"_a.noconvert())
        .def("shade",
             [](PhotonGatherer &g, Array<float> tfar, Array<int32_t> prim, Array<float> u, Array<float> v,
                double surface_radius, double volume_radius) {
                 Hits h = hits_of(tfar, prim, u, v);
                 released([&] { g.shade(h, surface_radius, volume_radius); });
             })
        .def("next_rays",
             [](PhotonGatherer &g, Array<float> o, Array<float> d, Array<float> t) {
                 RayBuffers b = ray_buffers(o, d, t);
                 return released([&] { return g.next_rays(b); });
             }, "o"_a.noconvert(), "d"_a.noconvert(), "t"_a.noconvert())
        .def("end_iteration", &PhotonGatherer::end_iteration, nb::call_guard<nb::gil_scoped_release>())
        .def("image", [](const PhotonGatherer &g) { return film_image(g.film()); })
        .def_prop_ro("samples_per_pixel", [](const PhotonGatherer &g) { return g.film().samples_per_pixel; })
        .def_prop_ro("nonfinite", [](const PhotonGatherer &g) { return g.film().nonfinite; })
        .def_prop_ro("density_lookups", &PhotonGatherer::density_lookups)
        .def_prop_ro("surface_photons", [](const PhotonGatherer &g) { return g.stats().surface_photons; })
        .def_prop_ro("volume_photons", [](const PhotonGatherer &g) { return g.stats().volume_photons; })
        .def_prop_ro("surface_lookups", [](const PhotonGatherer &g) { return g.stats().surface_lookups; })
        .def_prop_ro("volume_lookups", [](const PhotonGatherer &g) { return g.stats().volume_lookups; });
}

}  // namespace pgi::bind
