// Bindings of the photon-mapping kernel (pm.h, shared by pm and sppm), the photon
// kd-tree (photon_map.h, exposed for tests) and the radius schedule.
#include "pilot_bind.h"
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

static void bind_pm(nb::module_ &m) {
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
             }, "origin"_a, "direction"_a, "tmax"_a, "radius"_a)
        // The distance within which the k nearest points lie (inf: fewer within max_radius).
        .def("kth_nearest_to_point",
             [](const PointTree &t, V3 c, size_t k, double max_radius) {
                 return t.kth_nearest_to_point(vec(c), k, max_radius, [](uint32_t) { return true; });
             }, "center"_a, "k"_a, "max_radius"_a)
        .def("kth_nearest_to_segment",
             [](const PointTree &t, V3 o, V3 d, double tmax, size_t k, double max_radius) {
                 return t.kth_nearest_to_segment(vec(o), normalize(vec(d)), tmax, k, max_radius,
                                                 [](uint32_t) { return true; });
             }, "origin"_a, "direction"_a, "tmax"_a, "k"_a, "max_radius"_a);

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

    auto cls = bind_kernel<PhotonMapping>(m, "PhotonMapping");
    cls
        .def(nb::init<std::shared_ptr<const Scene>, std::shared_ptr<const LightPaths>, int, uint64_t, int, int, double,
                      double, double, double>(),
             "scene"_a, "light_paths"_a, "max_depth"_a, "seed"_a, "spp_per_iteration"_a, "threads"_a,
             "surface_radius"_a, "surface_alpha"_a, "volume_radius"_a, "volume_alpha"_a)
        .def("surface_radius", [](const PhotonMapping &g, int64_t it) { return g.surface_schedule().radius(it); },
             "iteration"_a)
        .def("volume_radius",
             [](const PhotonMapping &g, int64_t it, int medium) { return g.volume_schedule(medium).radius(it); },
             "iteration"_a, "medium"_a = 0)
        .def("set_surface_radius", &PhotonMapping::set_surface_radius, "radius"_a)
        .def("set_volume_radius", &PhotonMapping::set_volume_radius, "medium"_a, "radius"_a)
        .def_prop_ro("medium_count", &PhotonMapping::medium_count)
        .def_prop_ro("kernels",
                     [](const PhotonMapping &g) {
                         nb::list out;  // (alpha, dimension) of each blur: surfaces, then media (one alpha)
                         for (const RadiusSchedule *s : {&g.surface_schedule(), &g.volume_schedule(0)})
                             out.append(nb::make_tuple(s->alpha, s->dimension));
                         return out;
                     })
        .def_prop_ro("surface_photons", [](const PhotonMapping &g) { return g.stats().surface_photons; })
        .def_prop_ro("volume_photons", [](const PhotonMapping &g) { return g.stats().volume_photons; })
        .def_prop_ro("surface_lookups", [](const PhotonMapping &g) { return g.stats().surface_lookups; })
        .def_prop_ro("volume_lookups", [](const PhotonMapping &g) { return g.stats().volume_lookups; });
    bind_pilot(cls, "volume_neighbours");
}
PGI_BINDING("pm", bind_pm);

}  // namespace pgi::bind
