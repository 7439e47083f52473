// Binding of the direct-lighting example kernel (direct_lighting.h): bind_kernel gives it the
// passes of the iteration protocol; only its constructor is its own.
#include "bindings.h"
#include "direct_lighting.h"

namespace pgi::bind {

static void bind_direct_lighting(nb::module_ &m) {
    bind_kernel<DirectLighting>(m, "DirectLighting")
        .def(nb::init<std::shared_ptr<const Scene>, int, uint64_t, int, int>(), "scene"_a, "max_depth"_a, "seed"_a,
             "spp_per_iteration"_a, "threads"_a);
}
PGI_BINDING("direct", bind_direct_lighting);

}  // namespace pgi::bind
