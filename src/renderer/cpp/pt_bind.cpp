// Bindings of the pt kernel (see pt.h): the wave's first and last passes on the
// tracer, the passes between them on each lane.
#include "bindings.h"
#include "pt.h"

namespace pgi::bind {

using namespace nb::literals;

void bind_pt(nb::module_ &m) {
    nb::class_<PathTracerLane> lane_class(m, "PathTracerLane");
    def_shadow_passes(lane_class);
    lane_class
        .def("shade",
             [](PathTracerLane &lane, Array<float> tfar, Array<int32_t> prim, Array<float> u, Array<float> v) {
                 Hits h = hits_of(tfar, prim, u, v);
                 return released([&] { return lane.shade(h); });
             })
        .def("next_rays", [](PathTracerLane &lane, Array<float> o, Array<float> d, Array<float> t) {
            RayBuffers b = ray_buffers(o, d, t);
            return released([&] { return lane.next_rays(b); });
        }, "o"_a.noconvert(), "d"_a.noconvert(), "t"_a.noconvert());

    nb::class_<PathTracer>(m, "PathTracer")
        .def(nb::init<std::shared_ptr<const Scene>, int, int, uint64_t, int, int, int>(), "scene"_a, "max_depth"_a,
             "rr_depth"_a, "seed"_a, "spp_per_wave"_a, "lanes"_a, "slots_per_lane"_a)
        .def("lane", &PathTracer::lane, "index"_a, nb::rv_policy::reference_internal)
        .def("begin_wave", &PathTracer::begin_wave, "iteration"_a, nb::call_guard<nb::gil_scoped_release>())
        .def("end_wave", &PathTracer::end_wave, nb::call_guard<nb::gil_scoped_release>())
        .def("image", [](const PathTracer &pt) { return film_image(pt.film()); })
        .def_prop_ro("samples_per_pixel", [](const PathTracer &pt) { return pt.film().samples_per_pixel; })
        .def_prop_ro("nonfinite", [](const PathTracer &pt) { return pt.film().nonfinite; })
        .def_prop_ro("density_lookups", &PathTracer::density_lookups)
        .def_prop_ro("media_segments", &PathTracer::media_segments);
}

}  // namespace pgi::bind
