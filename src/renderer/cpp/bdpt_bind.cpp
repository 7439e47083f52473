// Bindings of the bdpt kernel (bdpt.h) and of its MIS probe for tests.
#include <nanobind/stl/vector.h>

#include "bdpt.h"
#include "bindings.h"

namespace pgi::bind {

static void bind_bdpt(nb::module_ &m) {
    bind_kernel<BidirectionalPathTracing>(m, "BidirectionalPathTracing")
        .def(nb::init<std::shared_ptr<const Scene>, std::shared_ptr<const LightPaths>,
                      std::shared_ptr<const CameraPaths>, int, uint64_t, int, int, int>(),
             "scene"_a, "light_paths"_a, "camera_paths"_a, "max_depth"_a, "seed"_a, "spp_per_iteration"_a,
             "threads"_a, "max_connect"_a)
        .def("set_strategy_images", &BidirectionalPathTracing::set_strategy_images, "on"_a)
        .def("strategy_images",
             [](const BidirectionalPathTracing &b) {
                 nb::dict out;  // (s, t) -> (weighted, unweighted), as images of the film's mean
                 for (const auto &[key, images] : b.strategy_images())
                     out[nb::make_tuple(key.first, key.second)] =
                         nb::make_tuple(film_image(images.weighted), film_image(images.unweighted));
                 return out;
             })
        .def_prop_ro("connections", &BidirectionalPathTracing::connections);

    // The MIS weights of every strategy of one path (bdpt_path_weights), given from its light end:
    // per vertex its position, kind (VertexKind), triangle, medium and light; per edge its
    // stand-in optical depth.
    m.def("bdpt_path_weights",
          [](const Scene &scene, Array<double> positions, Array<uint8_t> kinds, Array<int32_t> triangles,
             Array<int32_t> media, Array<int32_t> lights, Array<double> edge_tau, int max_connect) {
              const size_t n = kinds.shape(0);
              check_len(positions.shape(0), n, "positions");
              check_len(triangles.shape(0), n, "triangles");
              check_len(media.shape(0), n, "media");
              check_len(lights.shape(0), n, "lights");
              std::vector<PathVertex> path(n);
              for (size_t i = 0; i < n; ++i) {
                  const double *p = positions.data() + 3 * i;
                  path[i].pos = Vec3(p[0], p[1], p[2]);
                  path[i].kind = VertexKind(kinds.data()[i]);
                  path[i].triangle = triangles.data()[i];
                  path[i].medium = media.data()[i];
                  path[i].light = int16_t(lights.data()[i]);
                  if (path[i].kind == VertexKind::Surface)
                      path[i].delta = scene.materials[scene.triangles.at(size_t(path[i].triangle)).material].is_delta();
              }
              if (n > 0 && path[0].kind == VertexKind::Emission)
                  path[0].delta = scene.lights.at(size_t(path[0].light)).type != LightType::Area;
              std::vector<double> taus(edge_tau.data(), edge_tau.data() + edge_tau.shape(0));
              return bdpt_path_weights(scene, max_connect, path, taus);
          },
          "scene"_a, "positions"_a, "kinds"_a, "triangles"_a, "media"_a, "lights"_a, "edge_tau"_a, "max_connect"_a);
}
PGI_BINDING("bdpt", bind_bdpt);

}  // namespace pgi::bind
