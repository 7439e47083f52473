// Bindings of the pt kernel (see pt.h): one call per pass of a wave.
#include "bindings.h"
#include "pt.h"

namespace pgi::bind {

using namespace nb::literals;

void bind_pt(nb::module_ &m) {
    nb::class_<PathTracer> pt_class(m, "PathTracer");
    def_shadow_passes(pt_class);
    pt_class
        .def(nb::init<std::shared_ptr<const Scene>, int, int, uint64_t, int, int>(), "scene"_a, "max_depth"_a,
             "rr_depth"_a, "seed"_a, "spp_per_wave"_a, "threads"_a)
        .def_prop_ro("capacity", &PathTracer::capacity)
        .def("begin_wave",
             [](PathTracer &pt, int64_t it, Array<float> o, Array<float> d, Array<float> t) {
                 RayBuffers b = ray_buffers(o, d, t);
                 check_len(b.capacity, pt.capacity(), "ray buffers");
                 return released([&] { return pt.begin_wave(it, b); });
             })
        .def("shade",
             [](PathTracer &pt, Array<float> tfar, Array<int32_t> prim, Array<float> u, Array<float> v) {
                 Hits h = hits_of(tfar, prim, u, v);
                 return released([&] { return pt.shade(h); });
             })
        .def("next_rays",
             [](PathTracer &pt, Array<float> o, Array<float> d, Array<float> t) {
                 RayBuffers b = ray_buffers(o, d, t);
                 return released([&] { return pt.next_rays(b); });
             })
        .def("end_wave", &PathTracer::end_wave, nb::call_guard<nb::gil_scoped_release>())
        .def("image", [](const PathTracer &pt) { return film_image(pt.film()); })
        .def_prop_ro("samples_per_pixel", [](const PathTracer &pt) { return pt.film().samples_per_pixel; })
        .def_prop_ro("nonfinite", [](const PathTracer &pt) { return pt.film().nonfinite; })
        .def_prop_ro("density_lookups", &PathTracer::density_lookups)
        .def_prop_ro("media_segments", &PathTracer::media_segments)
        .def_prop_ro("paths_traced", &PathTracer::paths_traced);
}

}  // namespace pgi::bind
