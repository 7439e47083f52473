// Bindings of the ppb kernel (ppb.h) and of the beam BVH (beams.h, exposed for tests).
#include "pilot_bind.h"
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

static void bind_ppb(nb::module_ &m) {
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
             }, "origins"_a, "directions"_a, "tmax"_a)
        // For each ray: the distance within which its k nearest beams lie (inf: fewer within
        // max_radius); needs a tree built with radius 0.
        .def("kth_nearest",
             [](const BeamBvh &bvh, Array<double> origins, Array<double> dirs, Array<double> tmax, size_t k,
                double max_radius) {
                 size_t n = tmax.shape(0);
                 std::vector<double> out(n);
                 for (size_t i = 0; i < n; ++i) {
                     const double *o = origins.data() + 3 * i, *d = dirs.data() + 3 * i;
                     out[i] = bvh.kth_nearest(Vec3(o[0], o[1], o[2]), normalize(Vec3(d[0], d[1], d[2])),
                                              tmax.data()[i], k, max_radius, [](int32_t) { return true; });
                 }
                 return to_numpy(std::move(out), {n});
             }, "origins"_a, "directions"_a, "tmax"_a, "k"_a, "max_radius"_a)
        .def_prop_ro("beam_count", [](const BeamBvh &b) { return b.beams().size(); })
        .def_prop_ro("piece_count", &BeamBvh::piece_count)
        .def_prop_ro("node_count", &BeamBvh::node_count)
        .def_prop_ro("piece_length", &BeamBvh::piece_length)
        .def_prop_ro("truncated", &BeamBvh::truncated);

    auto cls = bind_kernel<ProgressivePhotonBeams>(m, "ProgressivePhotonBeams");
    cls
        .def(nb::init<std::shared_ptr<const Scene>, std::shared_ptr<const LightPaths>, int, int, uint64_t, int, int,
                      size_t, double, double, double, int>(),
             "scene"_a, "light_paths"_a, "max_depth"_a, "rr_depth"_a, "seed"_a, "spp_per_iteration"_a, "threads"_a,
             "max_beams"_a, "radius"_a, "alpha"_a, "max_piece_length"_a, "gather_diffuse_bounces"_a)
        .def("radius", &ProgressivePhotonBeams::radius, "iteration"_a, "medium"_a = 0)
        .def("set_beam_radius", &ProgressivePhotonBeams::set_beam_radius, "medium"_a, "radius"_a)
        .def("surface_radius", &ProgressivePhotonBeams::surface_radius, "iteration"_a)
        .def("set_surface_photons", &ProgressivePhotonBeams::set_surface_photons, "radius"_a, "alpha"_a)
        .def_prop_ro("kernels",
                     [](const ProgressivePhotonBeams &pb) {
                         nb::list out;  // (alpha, dimension) of each blur, as the schedules run them
                         for (const RadiusSchedule &s : pb.schedules()) out.append(nb::make_tuple(s.alpha, s.dimension));
                         return out;
                     })
        .def_prop_ro("photons_stored", [](const ProgressivePhotonBeams &pb) { return pb.stats().photons; })
        .def_prop_ro("beams_stored", [](const ProgressivePhotonBeams &pb) { return pb.stats().beams; })
        .def_prop_ro("beams_truncated", [](const ProgressivePhotonBeams &pb) { return pb.bvh().truncated(); })
        .def_prop_ro("beams_escaped", [](const ProgressivePhotonBeams &pb) { return pb.bvh().escaped(); })
        .def_prop_ro("beam_pairs", [](const ProgressivePhotonBeams &pb) { return pb.stats().beam_pairs; })
        .def_prop_ro("pieces", [](const ProgressivePhotonBeams &pb) { return pb.bvh().piece_count(); });
    bind_pilot(cls, "beam_neighbours");
}
PGI_BINDING("ppb", bind_ppb);

}  // namespace pgi::bind
