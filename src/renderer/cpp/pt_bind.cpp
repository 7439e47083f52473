// Bindings of the pt kernel (pt.h): the wave's begin and end on the kernel, the passes between
// them on each of its lanes.
#include "bindings.h"
#include "pt.h"

namespace pgi::bind {

using namespace nb::literals;

static void bind_pt(nb::module_ &m) {
    bind_kernel<PathTracing>(m, "PathTracing", "PathTracingLane")
        .def(nb::init<std::shared_ptr<const Scene>, int, int, uint64_t, int, int, int>(), "scene"_a, "max_depth"_a,
             "rr_depth"_a, "seed"_a, "spp_per_wave"_a, "lanes"_a, "slots_per_lane"_a)
        .def_prop_ro("media_segments", &PathTracing::media_segments);
}
PGI_BINDING("pt", bind_pt);

}  // namespace pgi::bind
