// Bindings of the shared light paths (lightpath.h) and of the lt kernel (lt.h).
#include <nanobind/stl/vector.h>

#include "bindings.h"
#include "lt.h"

namespace pgi::bind {

using namespace nb::literals;

namespace {

nb::dict vertex_arrays(const std::vector<PathVertex> &vs) {
    size_t n = vs.size();
    std::vector<double> pos(3 * n), wi(3 * n), throughput(3 * n), pdf_fwd(n), pdf_rev(n);
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

}  // namespace

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
    bind_kernel<LightPaths>(m, "LightPaths")
        .def(nb::init<std::shared_ptr<const Scene>, int, int, uint64_t, int64_t, int, int64_t>(), "scene"_a,
             "max_depth"_a, "rr_depth"_a, "seed"_a, "paths_per_iteration"_a, "threads"_a, "max_records"_a)
        .def("set_recording", &LightPaths::set_recording, "vertices"_a, "segments"_a, "complete"_a = false)
        .def_prop_ro("paths_per_iteration", &LightPaths::paths_per_iteration)
        .def("vertices", [](const LightPaths &lp) { return vertex_arrays(lp.vertices()); })
        .def("segments", [](const LightPaths &lp) { return segment_arrays(lp.segments()); })
        .def_prop_ro("vertex_count", [](const LightPaths &lp) { return lp.vertices().size(); })
        .def_prop_ro("segment_count", [](const LightPaths &lp) { return lp.segments().size(); })
        .def_prop_ro("paths_traced", &LightPaths::paths_traced);

    bind_kernel<LightTracing>(m, "LightTracing")
        .def(nb::init<std::shared_ptr<const Scene>, std::shared_ptr<const LightPaths>, uint64_t, int>(), "scene"_a,
             "light_paths"_a, "seed"_a, "threads"_a)
        .def_prop_ro("light_paths", &LightTracing::light_paths);
}
PGI_BINDING("lt", bind_lt);

}  // namespace pgi::bind
