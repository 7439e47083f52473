// Bindings of the lt kernel (lt.h) and of its camera projection probe.
#include "bindings.h"
#include "lt.h"

namespace pgi::bind {

using namespace nb::literals;

static void bind_lt(nb::module_ &m) {
    // Probe for tests: the pixel each world point projects to through connect_to_camera
    // (-1 off the film) and the importance it receives there.
    m.def("camera_projections",
          [](const Scene &s, Array<double> points) {
              size_t n = points.shape(0);
              std::vector<int64_t> pixel(n);
              std::vector<double> importance(n);
              for (size_t i = 0; i < n; ++i) {
                  const double *p = points.data() + 3 * i;
                  CameraConnection c = connect_to_camera(s.camera, Vec3(p[0], p[1], p[2]));
                  pixel[i] = c.valid ? c.pixel : -1;
                  importance[i] = c.importance;
              }
              return std::make_tuple(to_numpy(std::move(pixel), {n}), to_numpy(std::move(importance), {n}));
          }, "scene"_a, "points"_a);
    bind_kernel<LightTracing>(m, "LightTracing")
        .def(nb::init<std::shared_ptr<const Scene>, std::shared_ptr<const LightPaths>, uint64_t, int>(), "scene"_a,
             "light_paths"_a, "seed"_a, "threads"_a)
        .def_prop_ro("light_paths", &LightTracing::light_paths);
}
PGI_BINDING("lt", bind_lt);

}  // namespace pgi::bind
