// Bindings of the vpl kernel (vpl.h), of the kinds of virtual lights (virtual_lights.h) and of the
// probes tests use: equi-angular and truncated exponential sampling (equiangular.h) and the
// point light's transfer.
#include "virtual_lights_bind.h"

namespace pgi::bind {

using namespace nb::literals;

namespace {

// Samples t for uniforms u (n,) and their densities: equi-angular about `centre` on [t0, t1] of
// the ray (origin, direction).
auto equiangular_samples(V3 origin, V3 direction, double t0, double t1, V3 centre, Array<double> u) {
    const EquiAngular e = equiangular(vec(origin), normalize(vec(direction)), t0, t1, vec(centre));
    if (!e.valid) throw std::invalid_argument("equiangular: the centre lies on the ray's line or the segment is empty");
    const size_t n = u.shape(0);
    std::vector<double> t(n), pdf(n);
    for (size_t i = 0; i < n; ++i) {
        t[i] = equiangular_sample(e, u.data()[i]);
        pdf[i] = equiangular_pdf(e, t[i]);
    }
    return std::make_tuple(to_numpy(std::move(t), {n}), to_numpy(std::move(pdf), {n}));
}

auto equiangular_pdfs(V3 origin, V3 direction, double t0, double t1, V3 centre, Array<double> t) {
    const EquiAngular e = equiangular(vec(origin), normalize(vec(direction)), t0, t1, vec(centre));
    const size_t n = t.shape(0);
    std::vector<double> pdf(n);
    for (size_t i = 0; i < n; ++i) pdf[i] = equiangular_pdf(e, t.data()[i]);
    return std::make_tuple(to_numpy(std::move(pdf), {n}), equiangular_weight(e));
}

// The truncated exponential on [0, t1] at rate sigma: samples for uniforms u, and densities at t.
auto truncated_exponential_samples(double sigma, double t1, Array<double> u) {
    const TruncatedExponential e = truncated_exponential(sigma, t1);
    if (!e.valid) throw std::invalid_argument("truncated_exponential: sigma and t1 must be positive");
    const size_t n = u.shape(0);
    std::vector<double> t(n), pdf(n);
    for (size_t i = 0; i < n; ++i) {
        t[i] = truncated_exponential_sample(e, u.data()[i]);
        pdf[i] = truncated_exponential_pdf(e, t[i]);
    }
    return std::make_tuple(to_numpy(std::move(t), {n}), to_numpy(std::move(pdf), {n}));
}

}  // namespace

static void bind_vpl(nb::module_ &m) {
    nb::enum_<VirtualLightKind>(m, "VirtualLightKind")
        .value("surface", VirtualLightKind::Surface)
        .value("medium", VirtualLightKind::Medium)
        .value("area_light", VirtualLightKind::AreaLight)
        .value("point", VirtualLightKind::Point)
        .value("spot", VirtualLightKind::Spot)
        .value("directional", VirtualLightKind::Directional);
    nb::enum_<PointTransfer::Clamp>(m, "Clamp")
        .value("none", PointTransfer::Clamp::None)
        .value("fixed", PointTransfer::Clamp::Fixed)
        .value("progressive", PointTransfer::Clamp::Progressive);

    m.def("equiangular_samples", &equiangular_samples, "origin"_a, "direction"_a, "t0"_a, "t1"_a, "centre"_a, "u"_a,
          "Equi-angular points t on [t0, t1] about `centre` for uniforms u, with their densities.");
    m.def("equiangular_pdfs", &equiangular_pdfs, "origin"_a, "direction"_a, "t0"_a, "t1"_a, "centre"_a, "t"_a,
          "The equi-angular density at each t, and the weight (theta_1 - theta_0) / h.");
    m.def("truncated_exponential_samples", &truncated_exponential_samples, "sigma"_a, "t1"_a, "u"_a);
    m.def(
        "point_light_transfer",
        [](const Scene &s, V3 x_pos, V3 x_wo, int x_triangle, int x_medium, VirtualLightKind kind, V3 y_pos,
           V3 y_axis, int y_triangle, int y_medium, int y_light, double clamp_distance) {
            PointTransfer t;
            if (clamp_distance > 0) t.set_clamp(PointTransfer::Clamp::Fixed, clamp_distance, 1.0);
            t.begin(0);
            const GatherPoint x = probe_gather_point(s, x_pos, x_wo, x_triangle, x_medium);
            const VirtualLight y = probe_virtual_light(s, kind, y_pos, y_axis, y_triangle, y_medium, y_light);
            const Vec3 d = y.pos - x.pos;
            const double d2 = dot(d, d);
            const RGB k = t(s, x, y, d / std::sqrt(d2), d2, false, Sampler());
            return V3{k.x, k.y, k.z};
        },
        "scene"_a, "x_pos"_a, "x_wo"_a, "x_triangle"_a, "x_medium"_a, "kind"_a, "y_pos"_a, "y_axis"_a,
        "y_triangle"_a, "y_medium"_a, "y_light"_a, "clamp_distance"_a,
        "vpl's transfer F_x F_y / max(d^2, clamp_distance^2) from a virtual light of power 1 at y "
        "to the gather point x (on x_triangle, or in x_medium if x_triangle < 0).");

    using K = VirtualPointLights;
    auto cls = bind_kernel<K>(m, "VirtualPointLights");
    bind_clamp(bind_gathering(cls));
}
PGI_BINDING("vpl", bind_vpl);

}  // namespace pgi::bind
