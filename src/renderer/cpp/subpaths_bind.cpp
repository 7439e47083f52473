// Bindings of the subpath kernels (subpaths.h): light paths and camera paths, with their
// records as numpy arrays (for tests and for Python-side measurements).
#include <nanobind/stl/vector.h>

#include "bindings.h"
#include "subpaths.h"

namespace pgi::bind {

using namespace nb::literals;

namespace {

nb::dict vertex_arrays(const std::vector<PathVertex> &vs) {
    size_t n = vs.size();
    std::vector<double> pos(3 * n), wi(3 * n), throughput(3 * n), pdf_fwd(n), pdf_rev(n), tau_in(n);
    std::vector<int32_t> path(n), tri(n), medium(n);
    std::vector<int16_t> depth(n), light(n);
    std::vector<uint8_t> kind(n), delta(n), after_specular(n);
    for (size_t i = 0; i < n; ++i) {
        const PathVertex &v = vs[i];
        for (int a = 0; a < 3; ++a) {
            pos[3 * i + a] = v.pos[a];
            wi[3 * i + a] = v.wi[a];
            throughput[3 * i + a] = v.throughput[a];
        }
        pdf_fwd[i] = v.pdf_fwd;
        pdf_rev[i] = v.pdf_rev;
        tau_in[i] = v.tau_in;
        path[i] = v.path;
        tri[i] = v.triangle;
        medium[i] = v.medium;
        light[i] = v.light;
        depth[i] = v.depth;
        kind[i] = uint8_t(v.kind);
        delta[i] = v.delta;
        after_specular[i] = v.after_specular;
    }
    nb::dict d;
    d["position"] = to_numpy(std::move(pos), {n, 3});
    d["wi"] = to_numpy(std::move(wi), {n, 3});
    d["throughput"] = to_numpy(std::move(throughput), {n, 3});
    d["pdf_fwd"] = to_numpy(std::move(pdf_fwd), {n});
    d["pdf_rev"] = to_numpy(std::move(pdf_rev), {n});
    d["tau_in"] = to_numpy(std::move(tau_in), {n});
    d["path"] = to_numpy(std::move(path), {n});
    d["triangle"] = to_numpy(std::move(tri), {n});
    d["medium"] = to_numpy(std::move(medium), {n});
    d["light"] = to_numpy(std::move(light), {n});
    d["depth"] = to_numpy(std::move(depth), {n});
    d["kind"] = to_numpy(std::move(kind), {n});
    d["delta"] = to_numpy(std::move(delta), {n});
    d["after_specular"] = to_numpy(std::move(after_specular), {n});
    return d;
}

nb::dict segment_arrays(const std::vector<MediumSegment> &ss) {
    size_t n = ss.size();
    std::vector<double> origin(3 * n), dir(3 * n), power(3 * n), len(n), t_surface(n);
    std::vector<int32_t> path(n), medium(n);
    std::vector<int16_t> depth(n);
    std::vector<uint8_t> scattered(n);
    for (size_t i = 0; i < n; ++i) {
        const MediumSegment &s = ss[i];
        for (int a = 0; a < 3; ++a) {
            origin[3 * i + a] = s.origin[a];
            dir[3 * i + a] = s.dir[a];
            power[3 * i + a] = s.power[a];
        }
        len[i] = s.length;
        t_surface[i] = s.t_surface;
        path[i] = s.path;
        medium[i] = s.medium;
        depth[i] = s.depth;
        scattered[i] = s.scattered;
    }
    nb::dict d;
    d["origin"] = to_numpy(std::move(origin), {n, 3});
    d["direction"] = to_numpy(std::move(dir), {n, 3});
    d["power"] = to_numpy(std::move(power), {n, 3});
    d["length"] = to_numpy(std::move(len), {n});
    d["t_surface"] = to_numpy(std::move(t_surface), {n});
    d["path"] = to_numpy(std::move(path), {n});
    d["medium"] = to_numpy(std::move(medium), {n});
    d["depth"] = to_numpy(std::move(depth), {n});
    d["scattered"] = to_numpy(std::move(scattered), {n});
    return d;
}

template <Side S>
void bind_subpaths(nb::module_ &m, const char *name, const char *count) {
    using Kernel = Subpaths<S>;
    bind_kernel<Kernel>(m, name)
        .def(nb::init<std::shared_ptr<const Scene>, int, int, uint64_t, int64_t, int, int64_t>(), "scene"_a,
             "max_depth"_a, "rr_depth"_a, "seed"_a, nb::arg(count), "threads"_a, "max_records"_a)
        .def("set_recording", &Kernel::set_recording, "vertices"_a, "segments"_a, "complete"_a = false)
        .def_prop_ro("paths_per_iteration", &Kernel::paths_per_iteration)
        .def("vertices", [](const Kernel &k) { return vertex_arrays(k.vertices()); })
        .def("segments", [](const Kernel &k) { return segment_arrays(k.segments()); })
        .def_prop_ro("vertex_count", [](const Kernel &k) { return k.vertices().size(); })
        .def_prop_ro("segment_count", [](const Kernel &k) { return k.segments().size(); })
        .def_prop_ro("paths_traced", &Kernel::paths_traced);
}

}  // namespace

static void bind_all_subpaths(nb::module_ &m) {
    bind_subpaths<Side::Light>(m, "LightPaths", "paths_per_iteration");
    bind_subpaths<Side::Camera>(m, "CameraPaths", "spp_per_iteration");
}
PGI_BINDING("subpaths", bind_all_subpaths);

}  // namespace pgi::bind
