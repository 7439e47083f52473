// Bindings of the ppb kernel (ppb.h) and of the beam BVH (beams.h, exposed for tests).
#include "bindings.h"
#include "ppb.h"

namespace pgi::bind {

using namespace nb::literals;

namespace {

// Beams from arrays, for tests: power 1, medium 0, depth 0.
std::vector<Beam> beams_of(Array<double> origins, Array<double> dirs, Array<double> lengths) {
    size_t n = lengths.shape(0);
    check_len(origins.shape(0), n, "origins");
    check_len(dirs.shape(0), n, "directions");
    std::vector<Beam> beams(n);
    for (size_t i = 0; i < n; ++i) {
        const double *o = origins.data() + 3 * i, *d = dirs.data() + 3 * i;
        beams[i].origin = {o[0], o[1], o[2]};
        beams[i].dir = normalize(Vec3(d[0], d[1], d[2]));
        beams[i].length = lengths.data()[i];
        beams[i].power = RGB(1.0);
        beams[i].medium = 0;
    }
    return beams;
}

}  // namespace

void bind_ppb(nb::module_ &m) {
    nb::class_<BeamBvh>(m, "BeamBvh")
        .def(nb::init<size_t>(), "max_beams"_a)
        .def(
            "build",
            [](BeamBvh &bvh, Array<double> origins, Array<double> dirs, Array<double> lengths, double radius,
               double max_piece_length) {
                std::vector<Beam> beams = beams_of(origins, dirs, lengths);
                released([&] { bvh.build(std::move(beams), radius, max_piece_length); });
            },
            "origins"_a, "directions"_a, "lengths"_a, "radius"_a, "max_piece_length"_a)
        // All hits of a batch of rays: (ray, beam, t_beam, t_ray, distance, sin_theta) arrays,
        // rays in order, beams in the tree's visiting order.
        .def("query",
             [](const BeamBvh &bvh, Array<double> origins, Array<double> dirs, Array<double> tmax) {
                 size_t n = tmax.shape(0);
                 std::vector<int64_t> ray, beam;
                 std::vector<double> tb, tr, dist, sine;
                 {
                     nb::gil_scoped_release release;
                     for (size_t i = 0; i < n; ++i) {
                         const double *o = origins.data() + 3 * i, *d = dirs.data() + 3 * i;
                         bvh.query(Vec3(o[0], o[1], o[2]), normalize(Vec3(d[0], d[1], d[2])), tmax.data()[i],
                                   [&](int32_t b, const BeamHit &h) {
                                       ray.push_back(int64_t(i));
                                       beam.push_back(b);
                                       tb.push_back(h.t_beam);
                                       tr.push_back(h.t_ray);
                                       dist.push_back(h.distance);
                                       sine.push_back(h.sin_theta);
                                   });
                     }
                 }
                 size_t k = ray.size();
                 return nb::make_tuple(to_numpy(std::move(ray), {k}), to_numpy(std::move(beam), {k}),
                                       to_numpy(std::move(tb), {k}), to_numpy(std::move(tr), {k}),
                                       to_numpy(std::move(dist), {k}), to_numpy(std::move(sine), {k}));
             })
        .def_prop_ro("beam_count", [](const BeamBvh &b) { return b.beams().size(); })
        .def_prop_ro("piece_count", &BeamBvh::piece_count)
        .def_prop_ro("node_count", &BeamBvh::node_count)
        .def_prop_ro("piece_length", &BeamBvh::piece_length)
        .def_prop_ro("truncated", &BeamBvh::truncated);

    nb::class_<PhotonBeams> beams_class(m, "PhotonBeams");
    def_shadow_passes(beams_class);
    beams_class
        .def(nb::init<std::shared_ptr<const Scene>, int, int, uint64_t, int, int, size_t, double, double, int>(),
             "scene"_a, "max_depth"_a, "rr_depth"_a, "seed"_a, "spp_per_iteration"_a, "threads"_a, "max_beams"_a,
             "radius"_a, "alpha"_a, "gather_diffuse_bounces"_a)
        .def("radius", &PhotonBeams::radius, "iteration"_a)
        .def("surface_radius", &PhotonBeams::surface_radius, "iteration"_a)
        .def("set_surface_photons", &PhotonBeams::set_surface_photons, "radius"_a, "alpha"_a)
        .def_prop_ro("kernels",
                     [](const PhotonBeams &pb) {
                         nb::list out;  // (alpha, dimension) of each blur, as the schedules run them
                         for (const RadiusSchedule &s : pb.schedules()) out.append(nb::make_tuple(s.alpha, s.dimension));
                         return out;
                     })
        .def_prop_ro("photons_stored", [](const PhotonBeams &pb) { return pb.stats().photons; })
        .def_prop_ro("capacity", &PhotonBeams::capacity)
        .def(
            "build_beams",
            [](PhotonBeams &pb, const LightPathTracer &light, int64_t iteration, double max_piece_length) {
                released([&] { pb.build_beams(light, iteration, max_piece_length); });
            },
            "light_paths"_a, "iteration"_a, "max_piece_length"_a)
        .def("begin_wave",
             [](PhotonBeams &pb, int64_t it, Array<float> o, Array<float> d, Array<float> t) {
                 RayBuffers b = ray_buffers(o, d, t);
                 check_len(b.capacity, pb.capacity(), "ray buffers");
                 return released([&] { return pb.begin_wave(it, b); });
             }, "iteration"_a, "o"_a.noconvert(), "d"_a.noconvert(), "t"_a.noconvert())
        .def("shade",
             [](PhotonBeams &pb, Array<float> tfar, Array<int32_t> prim, Array<float> u, Array<float> v) {
                 Hits h = hits_of(tfar, prim, u, v);
                 return released([&] { return pb.shade(h); });
             })
        .def("next_rays",
             [](PhotonBeams &pb, Array<float> o, Array<float> d, Array<float> t) {
                 RayBuffers b = ray_buffers(o, d, t);
                 return released([&] { return pb.next_rays(b); });
             }, "o"_a.noconvert(), "d"_a.noconvert(), "t"_a.noconvert())
        .def("end_wave", &PhotonBeams::end_wave, nb::call_guard<nb::gil_scoped_release>())
        .def("image", [](const PhotonBeams &pb) { return film_image(pb.film()); })
        .def_prop_ro("samples_per_pixel", [](const PhotonBeams &pb) { return pb.film().samples_per_pixel; })
        .def_prop_ro("nonfinite", [](const PhotonBeams &pb) { return pb.film().nonfinite; })
        .def_prop_ro("beams_stored", [](const PhotonBeams &pb) { return pb.stats().beams; })
        .def_prop_ro("beams_truncated", [](const PhotonBeams &pb) { return pb.bvh().truncated(); })
        .def_prop_ro("beams_escaped", [](const PhotonBeams &pb) { return pb.bvh().escaped(); })
        .def_prop_ro("beam_pairs", [](const PhotonBeams &pb) { return pb.stats().beam_pairs; })
        .def_prop_ro("density_lookups", [](const PhotonBeams &pb) { return pb.stats().density_lookups; })
        .def_prop_ro("pieces", [](const PhotonBeams &pb) { return pb.bvh().piece_count(); });
}

}  // namespace pgi::bind
