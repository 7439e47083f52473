// Bindings of the vrl / vbl kernel (vrl.h, ray_lights.h) and of the probes its tests use: the
// density on a ray light, the beam's disc mean of 1 / d^2, and single-pair estimates.
#include "virtual_lights_bind.h"
#include "vbl.h"

namespace pgi::bind {

using namespace nb::literals;

namespace {

RayLight probe_ray_light(const Scene &s, V3 origin, V3 direction, double length, int medium) {
    if (medium < 0 || medium >= int(s.media.size()))
        throw std::invalid_argument("ray light: a medium of the scene expected");
    if (!(length > 0) || !std::isfinite(length)) throw std::invalid_argument("ray light: a positive length expected");
    RayLight l;
    l.origin = vec(origin);
    l.dir = normalize(vec(direction));
    l.length = length;
    l.power = RGB(1.0);
    l.medium = medium;
    return l;
}

// Samples v for uniforms u (n,) on the ray light (origin, direction, [0, length)) by the density
// about the camera line (camera_origin, camera_direction), and their densities.
auto line_to_line_samples(V3 origin, V3 direction, double length, V3 camera_origin, V3 camera_direction,
                          double min_h, double soften, Array<double> u) {
    const LineToLine s = line_to_line(vec(origin), normalize(vec(direction)), length, vec(camera_origin),
                                      normalize(vec(camera_direction)), min_h, soften);
    if (!s.valid) throw std::invalid_argument("line_to_line: no density (empty or infinite ray light)");
    const size_t n = u.shape(0);
    std::vector<double> v(n), pdf(n);
    for (size_t i = 0; i < n; ++i) {
        v[i] = line_to_line_sample(s, u.data()[i]);
        pdf[i] = line_to_line_pdf(s, v[i]);
    }
    return std::make_tuple(to_numpy(std::move(v), {n}), to_numpy(std::move(pdf), {n}), s.uniform);
}

auto line_to_line_pdfs(V3 origin, V3 direction, double length, V3 camera_origin, V3 camera_direction, double min_h,
                       double soften, Array<double> v) {
    const LineToLine s = line_to_line(vec(origin), normalize(vec(direction)), length, vec(camera_origin),
                                      normalize(vec(camera_direction)), min_h, soften);
    const size_t n = v.shape(0);
    std::vector<double> pdf(n);
    for (size_t i = 0; i < n; ++i) pdf[i] = line_to_line_pdf(s, v.data()[i]);
    return to_numpy(std::move(pdf), {n});
}

// Joins closer than this are skipped in probes (the kernel's bound for a scene of radius 1).
constexpr double kProbeMinDistance2 = kCoincidentFraction * kCoincidentFraction;

// The connection's transmittance for a probe: both ends in one homogeneous medium, no occluder.
RGB probe_connection(const Scene &s, int medium, const RayLightSample &x) {
    const Medium &m = s.media[size_t(medium)];
    if (m.type != MediumType::Homogeneous)
        throw std::invalid_argument("ray light probes: a homogeneous medium expected");
    return beer_lambert(m.sigma_t, length(x.y - x.x));
}

// Phase-aware equi-angular points t about `centre` on [t0, t1] of the line (origin, direction),
// for uniforms u, with g the HG phase function of parameter g_line at the line's point (light
// travelling along `direction` and turning towards the centre) times the HG of g_centre at the
// centre (light arriving from the line and leaving along centre_out): t, its density, and the
// densities at `t_eval`.
auto phase_aware_samples(V3 origin, V3 direction, double t0, double t1, V3 centre, V3 centre_out, double g_line,
                         double g_centre, Array<double> u, Array<double> t_eval) {
    const Vec3 o = vec(origin), d = normalize(vec(direction)), c = vec(centre), out = normalize(vec(centre_out));
    const EquiAngular e = equiangular(o, d, t0, t1, c);
    if (!e.valid) throw std::invalid_argument("phase_aware_samples: the centre lies on the line");
    const Phase line_phase{PhaseType::HenyeyGreenstein, g_line, nullptr};
    const Phase centre_phase{PhaseType::HenyeyGreenstein, g_centre, nullptr};
    const AngularDensity a = angular_density(e, o, d, c, [&](const Vec3 &w) {
        // w: centre -> line point; light travels along d at the point, then to the centre, then out
        return phase_eval(line_phase, -d, -w) * phase_eval(centre_phase, w, out);
    });
    auto density = [&](double t) {
        const double s = t - e.t_closest;
        return angular_pdf(a, std::atan2(s, e.h)) * e.h / (e.h * e.h + s * s);
    };
    const size_t n = u.shape(0), m = t_eval.shape(0);
    std::vector<double> t(n), pdf(n), at(m);
    for (size_t i = 0; i < n; ++i) {
        double weight = 0;
        t[i] = equiangular_point(e, o, d, c, true, u.data()[i], [&](const Vec3 &w) {
            return phase_eval(line_phase, -d, -w) * phase_eval(centre_phase, w, out);
        }, weight);
        pdf[i] = density(t[i]);
    }
    for (size_t i = 0; i < m; ++i) at[i] = density(t_eval.data()[i]);
    return std::make_tuple(to_numpy(std::move(t), {n}), to_numpy(std::move(pdf), {n}), to_numpy(std::move(at), {m}));
}

}  // namespace

static void bind_vrl(nb::module_ &m) {
    m.def("line_to_line_samples", &line_to_line_samples, "origin"_a, "direction"_a, "length"_a, "camera_origin"_a,
          "camera_direction"_a, "min_h"_a, "soften"_a, "u"_a,
          "Points v on a ray light drawn by the density ~ 1 / distance to the camera line for "
          "uniforms u, their densities, and whether the lines counted as parallel (uniform v).");
    m.def("line_to_line_pdfs", &line_to_line_pdfs, "origin"_a, "direction"_a, "length"_a, "camera_origin"_a,
          "camera_direction"_a, "min_h"_a, "soften"_a, "v"_a);
    m.def("phase_aware_samples", &phase_aware_samples, "origin"_a, "direction"_a, "t0"_a, "t1"_a, "centre"_a,
          "centre_out"_a, "g_line"_a, "g_centre"_a, "u"_a, "t_eval"_a,
          "Phase-aware equi-angular points for uniforms u, their densities, and the density at t_eval.");
    m.def("beam_geometry_factor", &beam_geometry_factor, "z"_a, "rho2"_a, "radius"_a,
          "The disc's mean of 1 / |x - y'|^2 times (d^2 + r^2), x at height z and squared radial "
          "distance rho2 from a disc of `radius` (ray_lights.h).");
    m.def(
        "ray_light_segment_estimates",
        [](const Scene &s, V3 camera_origin, V3 camera_direction, double camera_length, int camera_medium,
           V3 light_origin, V3 light_direction, double light_length, int light_medium, double radius,
           bool phase_aware, int64_t n, uint64_t seed) {
            const RayLight l = probe_ray_light(s, light_origin, light_direction, light_length, light_medium);
            const V3 wo{-camera_direction[0], -camera_direction[1], -camera_direction[2]};
            const GatherPoint c = probe_gather_point(s, camera_origin, wo, -1, camera_medium);
            const Medium &mc = s.media[size_t(camera_medium)];
            if (mc.type != MediumType::Homogeneous || camera_medium != light_medium)
                throw std::invalid_argument("ray_light_segment_estimates: one homogeneous medium expected");
            auto camera_tr = [&](double u) { return beer_lambert(mc.sigma_t, u); };
            const size_t count = size_t(std::max<int64_t>(0, n));
            std::vector<double> out(3 * count);
            MediumStats ms;
            for (size_t i = 0; i < count; ++i) {
                Sampler rng(stream_key(seed, uint64_t(i), 0x56524cull));
                const RayLightSample x =
                    ray_light_to_segment(s, l, c, camera_length, camera_tr, radius, phase_aware, kProbeMinDistance2,
                                         rng, ms);
                const RGB k = is_black(x.value) ? RGB(0.0) : x.value * probe_connection(s, camera_medium, x);
                for (int a = 0; a < 3; ++a) out[3 * i + a] = k[a];
            }
            return to_numpy(std::move(out), {count, 3});
        },
        "scene"_a, "camera_origin"_a, "camera_direction"_a, "camera_length"_a, "camera_medium"_a, "light_origin"_a,
        "light_direction"_a, "light_length"_a, "light_medium"_a, "radius"_a, "phase_aware"_a, "n"_a, "seed"_a,
        "n independent estimates of a ray light's (power 1, depth 0) transport to a camera segment "
        "(throughput 1), with the connection's transmittance and no occluder (ray_lights.h).");
    m.def(
        "ray_light_point_estimates",
        [](const Scene &s, V3 x_pos, V3 x_wo, int x_triangle, int x_medium, V3 light_origin, V3 light_direction,
           double light_length, int light_medium, double radius, bool phase_aware, int64_t n, uint64_t seed) {
            const RayLight l = probe_ray_light(s, light_origin, light_direction, light_length, light_medium);
            const GatherPoint x = probe_gather_point(s, x_pos, x_wo, x_triangle, x_medium);
            const size_t count = size_t(std::max<int64_t>(0, n));
            std::vector<double> out(3 * count);
            MediumStats ms;
            for (size_t i = 0; i < count; ++i) {
                Sampler rng(stream_key(seed, uint64_t(i), 0x56524cull));
                const RayLightSample y = ray_light_to_point(s, l, x, radius, phase_aware, kProbeMinDistance2, rng, ms);
                const RGB k = is_black(y.value) ? RGB(0.0) : y.value * probe_connection(s, light_medium, y);
                for (int a = 0; a < 3; ++a) out[3 * i + a] = k[a];
            }
            return to_numpy(std::move(out), {count, 3});
        },
        "scene"_a, "x_pos"_a, "x_wo"_a, "x_triangle"_a, "x_medium"_a, "light_origin"_a, "light_direction"_a,
        "light_length"_a, "light_medium"_a, "radius"_a, "phase_aware"_a, "n"_a, "seed"_a,
        "n independent estimates of a ray light's (power 1) transport to the gather point x, with the "
        "connection's transmittance and no occluder (ray_lights.h).");

    using K = VirtualRayLights;
    auto cls = bind_kernel<K>(m, "VirtualRayLights");
    bind_clamp(bind_gathering(cls))
        .def("set_beam_radius", [](K &k, double initial, double alpha) { k.extra().set_beam_radius(initial, alpha); },
             "initial"_a, "alpha"_a, "Beams (vbl) of radius r_i = r_1 i^(alpha - 1), world units.")
        .def("set_min_depth", &K::set_min_depth, "min_depth"_a,
             "Only paths of at least min_depth - 1 real scattering events reach the image (Mitsuba's "
             "count of vertices: 3 leaves multiple scattering alone).")
        .def_prop_ro("min_depth", &K::min_depth)
        .def("set_phase_sampling", [](K &k, bool on) { k.extra().set_phase_sampling(on); }, "on"_a,
             "Equi-angular angles drawn by the phase functions' fitted product (ray_lights.h).")
        .def("beam_radius", [](const K &k, int64_t iteration) { return k.extra().radius(iteration); },
             "iteration"_a, "The beams' radius (0: rays) of iteration `iteration` (0-based).");
}
PGI_BINDING("vrl", bind_vrl);

}  // namespace pgi::bind
