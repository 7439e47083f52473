// Bindings of the vsl kernel (vsl.h) and of its transfer as a probe.
#include "virtual_lights_bind.h"
#include "vsl.h"

namespace pgi::bind {

using namespace nb::literals;

static void bind_vsl(nb::module_ &m) {
    m.def(
        "sample_uniform_narrow_cone",
        [](V3 axis, double one_minus_cos, Array<double> u) {
            if (u.ndim() != 2 || u.shape(1) != 2) throw std::invalid_argument("u must be (n, 2)");
            if (!(one_minus_cos > 0 && one_minus_cos <= 2))
                throw std::invalid_argument("one_minus_cos must lie in (0, 2]");
            const size_t n = u.shape(0);
            const Vec3 a = normalize(vec(axis));
            std::vector<double> dir(3 * n);
            for (size_t i = 0; i < n; ++i) {
                const Vec3 d = square_to_uniform_narrow_cone(a, one_minus_cos, u.data()[2 * i], u.data()[2 * i + 1]);
                for (int k = 0; k < 3; ++k) dir[3 * i + size_t(k)] = d[k];
            }
            return to_numpy(std::move(dir), {n, 3});
        },
        "axis"_a, "one_minus_cos"_a, "u"_a,
        "Directions uniform in solid angle within the cone about `axis` whose half-angle has "
        "1 - cos = one_minus_cos (vsl's cone strategy), for uniforms u (n, 2).");
    m.def(
        "spherical_light_transfers",
        [](const Scene &s, V3 x_pos, V3 x_wo, int x_triangle, int x_medium, VirtualLightKind kind, V3 y_pos,
           V3 y_axis, int y_triangle, int y_medium, int y_light, double radius, int64_t n, uint64_t seed) {
            if (!(radius > 0)) throw std::invalid_argument("spherical_light_transfers: radius must be positive");
            const GatherPoint x = probe_gather_point(s, x_pos, x_wo, x_triangle, x_medium);
            const VirtualLight y = probe_virtual_light(s, kind, y_pos, y_axis, y_triangle, y_medium, y_light);
            const Vec3 d = y.pos - x.pos;
            const double d2 = dot(d, d);
            std::vector<double> out(3 * size_t(std::max<int64_t>(0, n)));
            for (int64_t i = 0; i < n; ++i) {
                const RGB k = spherical_light_transfer(s, x, y, d / std::sqrt(d2), d2, radius,
                                                       Sampler(stream_key(seed, uint64_t(i), 0x56534cull)), false);
                for (int a = 0; a < 3; ++a) out[3 * size_t(i) + a] = k[a];
            }
            return to_numpy(std::move(out), {size_t(std::max<int64_t>(0, n)), 3});
        },
        "scene"_a, "x_pos"_a, "x_wo"_a, "x_triangle"_a, "x_medium"_a, "kind"_a, "y_pos"_a, "y_axis"_a,
        "y_triangle"_a, "y_medium"_a, "y_light"_a, "radius"_a, "n"_a, "seed"_a,
        "n independent estimates of vsl's transfer K(x, y) from a virtual light of power 1 spread "
        "over a sphere of `radius` (vsl.h).");

    using K = VirtualSphericalLights;
    auto cls = bind_kernel<K>(m, "VirtualSphericalLights");
    bind_gathering(cls)
        .def("set_radius", [](K &k, double initial, double alpha) { k.transfer().set_radius(initial, alpha); },
             "initial"_a, "alpha"_a, "The sphere's radius r_i = r_1 i^(alpha - 1), world units.")
        .def("radius", [](const K &k, int64_t iteration) { return k.transfer().radius(iteration); }, "iteration"_a,
             "The sphere's radius in world units of iteration `iteration` (0-based).");
}
PGI_BINDING("vsl", bind_vsl);

}  // namespace pgi::bind
