// Ray lights: the medium segments of light paths kept as light sources of their own, gathered
// by vrl (virtual ray lights) and vbl (progressive virtual beam lights, rays thickened into
// beams of a shrinking radius).
//   Novak, Nowrouzezahrai, Dachsbacher & Jarosz 2012, "Virtual ray lights for rendering scenes
//     with participating media", ACM TOG 31(4) (SIGGRAPH): the ray light, its transport to a
//     camera ray (their eq. 4-5) and the sampling of the pair of points (their sec. 4);
//   Novak, Nowrouzezahrai, Dachsbacher & Jarosz 2012, "Progressive virtual beam lights", CGF
//     31(4) (EGSR): ray lights thickened into beams whose radius shrinks progressively;
//   Kulla & Fajardo 2012 for the equi-angular density (equiangular.h).
//
// A ray light (RayLight) is a straight piece y(v) = o + v w_l, v in [0, l), of a light path
// inside one medium, with the path's flux weight Phi at o (divided by the light paths N).
// Short ray lights: a piece ends at the collision the light tracer sampled on it (or at the
// surface where none was), and that collision is the origin of the path's next piece, so no flux
// is counted twice. Flux reaches y(v) with weight W(v) = Tr(o, y(v)) / P(t > v), the
// probability that the sampled flight passes v standing in for the transmittance (subpaths.h):
// 1 in density grids (delta tracking is analogue and grey), Tr_c(v) / mean_c(ratio_c Tr_c(v))
// for the hero-channel flights of chromatic homogeneous media. In a grid, a piece is cut to
// the grid's box (no scattering outside it).
//
// Transport to a camera segment x(u) = c + u w_c, u in [0, s), of throughput beta at c
// (Novak et al. 2012, eq. 4):
//   L = beta Phi int_0^s int_0^l Tr(c, x) sigma_s(x) f_x(w) W(v) sigma_s(y) f_y(-w) V Tr(x, y)
//                                  / |x - y|^2 dv du,     w = (y - x) / |x - y|
// with f_x the phase function at x for the camera's direction (gather_scattering) and f_y the
// one at y for light arriving along w_l (virtual_light_emission of a medium point). One sample
// (v, u) per camera segment and ray light:
//   v ~ p(v) = sin(theta) / ((A_1 - A_0) sqrt(h^2 + (v - v_c)^2 sin^2(theta))),
//       A_k = asinh((v_k - v_c) sin(theta) / h),  v = v_c + h sinh(A_0 + xi (A_1 - A_0)) / sin(theta)
//   (Novak et al. 2012, sec. 4.1: the density proportional to 1 / the distance from y(v) to the
//   camera ray's line, which is what the inner integral of 1 / |x - y|^2 over an infinite line
//   leaves, pi / dist; theta the angle between the lines, h their distance, v_c the ray light's
//   point closest to the camera line, [v_0, v_1] = [0, l]);
//   u ~ equi-angular about y(v) on [0, s) (sec. 4.2; equiangular.h), p(u) = h_v / (Theta |x - y|^2)
//   with h_v the distance from y(v) to the camera line and Theta the angle [0, s) subtends at y;
//   so the sample's weight 1 / (|x - y|^2 p(v) p(u)) is Theta / (h_v p(v)) =
//   (A_1 - A_0) Theta / sin(theta): bounded as the lines turn parallel, growing as log(1 / h) as
//   they meet. Nearly parallel lines (sin(theta) < 1e-4) draw v uniformly (p = 1 / l, weight
//   Theta l / h_v); h is floored at the skipped-join distance (vpl.h), so intersecting lines keep
//   a finite density; a y(v) on the camera line (h_v = 0) is skipped (measure zero).
// Transport to a surface point x (beta its camera path's throughput):
//   L = beta Phi int_0^l f_x(w) W(v) sigma_s(y) f_y(-w) V Tr(x, y) / |x - y|^2 dv,
//   v equi-angular about x on the ray light: weight Theta_x / h_x (h_x: x's distance to the line).
// The joined path has depth + 1 events on the light side (y(v) is a scattering event after the
// ray light's origin) and the job's on the camera side: gathered iff DepthLimit::allows.
//
// Beams (vbl). The flux of each point y(v) is spread uniformly over the disc of radius r about it,
// perpendicular to w_l (the beam's cross-section); the other factors are taken at y(v) (the
// beam's axis). 1 / |x - y|^2 becomes the disc's mean, in closed form for x at height z above the
// disc's plane and distance rho from its axis:
//   G_r(x, y) = (1 / (pi r^2)) int_disc dA / |x - y'|^2 = ln(R) / r^2,
//   R = (S + r^2 + z^2 - rho^2) / (2 z^2),  S = sqrt((z^2 + rho^2 + r^2)^2 - 4 rho^2 r^2)
// (R = 1 + r^2 / z^2 on the axis; for rho > r written as 2 rho^2 / (S - r^2 - z^2 + rho^2), which
// keeps its precision in the disc's plane) and G_r -> 1 / |x - y|^2 as r -> 0. The sampling
// densities soften h by r: p(v) with sqrt(h^2 + r^2) in place of h, and u equi-angular with
// sqrt(h_v^2 + r^2) (equiangular.h, `soften`), whose density is h' / (Theta' (|x - y|^2 + r^2));
// the weight G_r (|x - y|^2 + r^2) Theta' / (h' p(v)) is then finite for every pair of lines, a y
// on the camera line included. The radius shrinks as r_i = r_1 i^(alpha - 1) (radius_schedule.h with
// d = 1); vbl.h states why the mean converges.
//
// Phase-aware sampling (an option, `phase_sampling`; Novak et al. 2012, sec. 4.3 fit the phase
// functions' product over the equi-angular angle the same way). The equi-angular point is drawn
// uniformly in its angle phi in [phi_0, phi_1] about the centre (y(v) for a camera segment, x for
// a surface point); what the densities leave out is the angular factor g(phi): both phase
// functions (camera segment) or the ray light's phase function times F_x (surface point), which
// strongly forward-scattering media make peaked. With the option, phi is drawn from the
// piecewise-linear density through g at 11 evenly spaced angles, plus a tenth of their mean (so
// every angle keeps a density, whatever the fit misses):
//   p(phi) = g~(phi) / int g~,   t = t_c + h tan(phi),   p(t) = p(phi) h / (h^2 + (t - t_c)^2),
// and the equi-angular weight Theta / h becomes 1 / (p(phi) h). The ray light's v is drawn as
// before.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "equiangular.h"
#include "radius_schedule.h"
#include "vpl.h"

namespace pgi {

struct RayLight {
    Vec3 origin, dir;          // dir unit
    double length = 0;         // [0, length): to the sampled collision or the surface
    RGB power{0.0};            // Phi: flux weight at the origin, divided by the light paths
    RGB spectral_ratio{1.0};   // the light path's channel pdf ratios at the origin (W(v))
    int32_t medium = -1;
    int16_t depth = 0;         // real scattering events before the origin
};

// W(v): the weight of the flux reaching y(v) of a short ray light (above).
inline RGB ray_light_survival(const Medium &m, const RayLight &l, double v) {
    if (m.type != MediumType::Homogeneous) return RGB(1.0);
    const RGB tr = beer_lambert(m.sigma_t, v);
    const double passing = mean(l.spectral_ratio * tr);
    return passing > 0 ? tr / passing : RGB(0.0);
}

// This iteration's ray lights: one per recorded medium segment, in record order.
inline std::vector<RayLight> collect_ray_lights(const Scene &scene, const LightPaths &paths) {
    std::vector<RayLight> out;
    const double inv_paths = 1.0 / double(paths.paths_per_iteration());
    for (const MediumSegment &s : paths.segments()) {
        if (s.medium < 0) continue;
        const Medium &m = scene.media[size_t(s.medium)];
        RayLight l;
        l.origin = s.origin;
        l.dir = s.dir;
        l.length = std::min(s.length, s.t_surface);
        if (m.type == MediumType::Grid) {
            double lo = 0, hi = 0;  // W = 1 in grids: the piece may start at the box
            if (!grid_span(m, s.origin, s.dir, l.length, lo, hi)) continue;
            l.origin = s.origin + s.dir * lo;
            l.length = std::min(hi, l.length) - lo;
        }
        if (!(l.length > 0) || !std::isfinite(l.length)) continue;  // infinite: no medium to scatter in
        l.power = s.power * inv_paths;
        l.spectral_ratio = s.spectral_ratio;
        l.medium = s.medium;
        l.depth = s.depth;
        if (!is_black(l.power)) out.push_back(l);
    }
    return out;
}

// The density of a point on a ray light y(v) = o + v w_l, v in [0, l), proportional to 1 / its
// distance to the camera line c + u w_c (above; Novak et al. 2012, sec. 4.1).
struct LineToLine {
    double v_closest = 0, h = 0, sin_theta = 0, length = 0;
    double A0 = 0, A1 = 0;
    bool uniform = false;  // nearly parallel lines: uniform on [0, l)
    bool valid = false;
};

constexpr double kParallelSine = 1e-4;

// `min_h` floors the lines' distance, `soften` (vbl's radius) softens it: sqrt(h^2 + soften^2).
inline LineToLine line_to_line(const Vec3 &o, const Vec3 &wl, double length, const Vec3 &c, const Vec3 &wc,
                               double min_h, double soften) {
    LineToLine s;
    s.length = length;
    if (!(length > 0) || !std::isfinite(length)) return s;
    const Vec3 w0 = o - c;
    const Vec3 normal = cross(wc, wl);
    s.sin_theta = std::sqrt(dot(normal, normal));
    if (!(s.sin_theta > kParallelSine)) {
        s.uniform = s.valid = true;
        return s;
    }
    const double cos_theta = dot(wc, wl);
    s.v_closest = -(dot(w0, wl) - dot(w0, wc) * cos_theta) / (s.sin_theta * s.sin_theta);
    const double h = std::max(std::abs(dot(w0, normal)) / s.sin_theta, min_h);
    s.h = soften > 0 ? std::sqrt(h * h + soften * soften) : h;
    s.A0 = std::asinh((0 - s.v_closest) * s.sin_theta / s.h);
    s.A1 = std::asinh((length - s.v_closest) * s.sin_theta / s.h);
    s.valid = s.A1 > s.A0 && std::isfinite(s.A1 - s.A0);
    return s;
}

inline double line_to_line_sample(const LineToLine &s, double xi) {
    const double v = s.uniform ? xi * s.length
                               : s.v_closest + s.h * std::sinh(s.A0 + xi * (s.A1 - s.A0)) / s.sin_theta;
    return std::min(std::max(v, 0.0), s.length);
}

inline double line_to_line_pdf(const LineToLine &s, double v) {
    if (!s.valid || v < 0 || v > s.length) return 0.0;
    if (s.uniform) return 1.0 / s.length;
    const double off = (v - s.v_closest) * s.sin_theta;
    return s.sin_theta / ((s.A1 - s.A0) * std::sqrt(s.h * s.h + off * off));
}

// G_r(x, y) (|x - y|^2 + r^2): the disc's mean of 1 / |x - y'|^2 (above) times the softened
// distance; 1 for r = 0. z: x's height above the disc's plane, rho2: its squared distance from
// the disc's axis.
inline double beam_geometry_factor(double z, double rho2, double r) {
    const double z2 = z * z, d2 = z2 + rho2, r2 = r * r;
    if (r2 <= 1e-8 * d2) return 1.0 + r2 / d2;  // ln(R) / r^2 = 1 / d^2 to within 1e-8
    const double q = r2 + z2 - rho2;
    const double S = std::sqrt(std::max(0.0, (d2 + r2) * (d2 + r2) - 4 * rho2 * r2));
    const double R = q >= 0 ? (S + q) / (2 * std::max(z2, 1e-300)) : 2 * rho2 / (S - q);
    return std::log(R) / r2 * (d2 + r2);
}

// The phase-aware density of the equi-angular angle (above) on the line o + t d about `centre`:
// `factor(w)` is g for the unit direction w from the centre to the line's point at angle phi.
struct AngularDensity {
    static constexpr int kNodes = 11;
    double phi0 = 0, step = 0, total = 0;
    std::array<double, kNodes> value{}, mass{};  // g~ at the nodes; mass of [phi_0, phi_k]
};

template <typename Factor>
AngularDensity angular_density(const EquiAngular &e, const Vec3 &o, const Vec3 &d, const Vec3 &centre,
                               Factor &&factor) {
    constexpr int K = AngularDensity::kNodes;
    AngularDensity a;
    a.phi0 = std::atan(e.tan0);
    a.step = e.range() / (K - 1);
    Vec3 n = o + d * e.t_closest - centre;  // towards the line's nearest point
    const double off = length(n);
    n = off > 0 ? n / off : Frame(d).s;     // a centre on the line (softened beams): any normal
    double sum = 0;
    for (int k = 0; k < K; ++k) {
        const double phi = a.phi0 + k * a.step;
        a.value[size_t(k)] = std::max(0.0, factor(n * std::cos(phi) + d * std::sin(phi)));
        sum += a.value[size_t(k)];
    }
    const double floor = sum > 0 && std::isfinite(sum) ? 0.1 * sum / K : 1.0;
    for (int k = 0; k < K; ++k) {
        double &g = a.value[size_t(k)];
        g = std::isfinite(sum) ? g + floor : 1.0;
        if (k > 0) a.mass[size_t(k)] = a.mass[size_t(k - 1)] + 0.5 * (a.value[size_t(k - 1)] + g) * a.step;
    }
    a.total = a.mass[K - 1];
    return a;
}

// phi for a uniform xi, and its density p(phi).
inline double angular_sample(const AngularDensity &a, double xi, double &pdf) {
    constexpr int K = AngularDensity::kNodes;
    const double target = xi * a.total;
    int k = 0;
    while (k < K - 2 && a.mass[size_t(k + 1)] < target) ++k;
    const double g0 = a.value[size_t(k)], g1 = a.value[size_t(k + 1)];
    const double in = std::max(0.0, (target - a.mass[size_t(k)]) / a.step);  // area within, per unit step
    // the linear density g0 + (g1 - g0) s over s in [0, 1]: its integral to s is `in`
    const double s = std::min(1.0, 2 * in / (g0 + std::sqrt(std::max(0.0, g0 * g0 + 2 * (g1 - g0) * in))));
    pdf = (g0 + (g1 - g0) * s) / a.total;
    return a.phi0 + (k + s) * a.step;
}

inline double angular_pdf(const AngularDensity &a, double phi) {
    constexpr int K = AngularDensity::kNodes;
    const double x = (phi - a.phi0) / a.step;
    if (!(x >= 0 && x <= K - 1)) return 0.0;
    const int k = std::min(int(x), K - 2);
    const double s = x - k;
    return (a.value[size_t(k)] + (a.value[size_t(k + 1)] - a.value[size_t(k)]) * s) / a.total;
}

// A point t on the equi-angular distribution e of the line (o, d) about `centre`, plainly or by
// the phase-aware angle (factor: g), and 1 / (p(t) (|x(t) - centre|^2 + soften^2)): the weight
// that cancels the (softened) inverse-square distance.
template <typename Factor>
double equiangular_point(const EquiAngular &e, const Vec3 &o, const Vec3 &d, const Vec3 &centre, bool phase_aware,
                         double xi, Factor &&factor, double &weight) {
    if (!phase_aware) {
        weight = equiangular_weight(e);
        return equiangular_sample(e, xi);
    }
    const AngularDensity a = angular_density(e, o, d, centre, factor);
    double pdf_phi = 0;
    const double phi = angular_sample(a, xi, pdf_phi);
    weight = pdf_phi > 0 ? 1 / (pdf_phi * e.h) : 0.0;
    return std::min(std::max(e.t_closest + e.h * std::tan(phi), e.t0), e.t1);
}

// One sample of a ray light's transport to a gather point, before visibility and the
// connection's transmittance: `value` (camera throughput excluded), where on the ray light (y)
// and, for a segment, on the camera ray (x), and w = (y - x) / |y - x|. Zero value: nothing.
struct RayLightSample {
    RGB value{0.0};
    Vec3 x, y, w;
};

// To a surface point x (above).
inline RayLightSample ray_light_to_point(const Scene &scene, const RayLight &l, const GatherPoint &x, double radius,
                                        bool phase_aware, double min_distance2, Sampler &rng, MediumStats &ms) {
    RayLightSample s;
    const EquiAngular ea = equiangular(l.origin, l.dir, 0.0, l.length, x.pos, radius);
    if (!ea.valid) return s;
    const Medium &m = scene.media[size_t(l.medium)];
    double angular = 0;
    const double v = equiangular_point(ea, l.origin, l.dir, x.pos, phase_aware, rng.next(), [&](const Vec3 &w) {
        return phase_eval(m.phase, -l.dir, -w) * mean(gather_scattering(scene, x, w));
    }, angular);
    if (!(v > 0 && v < l.length)) return s;  // an end (rounding): on a surface, measure zero
    s.x = x.pos;
    s.y = l.origin + l.dir * v;
    const Vec3 d = s.y - s.x;
    const double d2 = dot(d, d);
    if (!(d2 > min_distance2)) return s;
    s.w = d / std::sqrt(d2);
    if (x.on_surface() && dot(scene.triangles[size_t(x.triangle)].n, s.w) <= 0) return s;
    const double z = dot(d, l.dir);
    const double geometry = beam_geometry_factor(z, std::max(0.0, d2 - z * z), radius) * angular;
    const RGB phase_y(phase_eval(m.phase, -l.dir, -s.w));
    s.value = l.power * ray_light_survival(m, l, v) * scattering_coefficient(m, s.y, ms) * phase_y *
              gather_scattering(scene, x, s.w) * geometry;
    return s;
}

// To the camera segment [0, length) of the ray (x.pos, -x.wo) in medium x.medium, whose
// transmittance from its origin `camera_tr` gives (above).
template <typename CameraTr>
RayLightSample ray_light_to_segment(const Scene &scene, const RayLight &l, const GatherPoint &camera, double length,
                                    CameraTr &&camera_tr, double radius, bool phase_aware, double min_distance2,
                                    Sampler &rng, MediumStats &ms) {
    RayLightSample s;
    const Vec3 c = camera.pos, wc = -camera.wo;
    const LineToLine pick = line_to_line(l.origin, l.dir, l.length, c, wc, std::sqrt(min_distance2), radius);
    if (!pick.valid) return s;
    const double v = line_to_line_sample(pick, rng.next());
    const double pdf_v = line_to_line_pdf(pick, v);
    if (!(v > 0 && v < l.length)) return s;  // an end (rounding): on a surface, measure zero
    s.y = l.origin + l.dir * v;
    const EquiAngular ea = equiangular(c, wc, 0.0, length, s.y, radius);
    if (!ea.valid || !(pdf_v > 0)) return s;
    const Medium &ml = scene.media[size_t(l.medium)];
    const Medium &mc = scene.media[size_t(camera.medium)];
    double angular = 0;  // w: from y towards the camera ray's point
    const double u = equiangular_point(ea, c, wc, s.y, phase_aware, rng.next(), [&](const Vec3 &w) {
        return phase_eval(ml.phase, -l.dir, w) * phase_eval(mc.phase, camera.wo, -w);
    }, angular);
    if (!(u > 0 && u < length)) return s;  // an end (rounding): on a surface, measure zero
    s.x = c + wc * u;
    const Vec3 d = s.y - s.x;
    const double d2 = dot(d, d);
    if (!(d2 > min_distance2)) return s;
    s.w = d / std::sqrt(d2);
    const double z = dot(d, l.dir);
    const double geometry = beam_geometry_factor(z, std::max(0.0, d2 - z * z), radius) * angular / pdf_v;
    const GatherPoint at{s.x, camera.wo, -1, camera.medium};
    const RGB phase_y(phase_eval(ml.phase, -l.dir, -s.w));
    s.value = camera_tr(u) * scattering_coefficient(mc, s.x, ms) * gather_scattering(scene, at, s.w) * l.power *
              ray_light_survival(ml, l, v) * scattering_coefficient(ml, s.y, ms) * phase_y * geometry;
    return s;
}

// The extra lights of vrl and vbl's gathering kernel (vpl.h: VirtualLightGathering's Extra):
// the iteration's ray lights, in place of the medium vertices' point lights.
class RayLights {
public:
    // Beams of radius r_i = r_1 i^(alpha - 1) (vbl, vbl.h); none (rays: vrl) by default.
    void set_beam_radius(double initial, double alpha) { schedule_ = RadiusSchedule(initial, alpha, 1); }
    bool beams() const { return schedule_.initial > 0; }
    // Phase-aware equi-angular angles (above).
    void set_phase_sampling(bool on) { phase_aware_ = on; }
    bool phase_sampling() const { return phase_aware_; }
    double radius(int64_t iteration) const { return beams() ? schedule_.radius(iteration) : 0.0; }
    const RadiusSchedule &schedule() const { return schedule_; }

    void begin(const Scene &scene, const LightPaths &paths, std::vector<VirtualLight> &lights, int64_t iteration) {
        lights.erase(std::remove_if(lights.begin(), lights.end(),
                                    [](const VirtualLight &v) { return v.kind == VirtualLightKind::Medium; }),
                     lights.end());
        rays_ = collect_ray_lights(scene, paths);
        radius_ = radius(iteration);
    }
    int64_t size() const { return int64_t(rays_.size()); }
    const std::vector<RayLight> &rays() const { return rays_; }

    void aim(const Scene &scene, const ExtraLightJob &c, int64_t index, Sampler &rng, ShadowRay &r,
             MediumStats &ms) const {
        const RayLight &l = rays_[size_t(index)];
        const GatherJob &J = c.job;
        if (!c.depth.allows(l.depth + 1 + J.events)) return;
        RayLightSample s;
        if (J.segment()) {
            const Medium &m = scene.media[size_t(J.at.medium)];
            auto camera_tr = [&](double u) {
                return m.type == MediumType::Homogeneous ? beer_lambert(m.sigma_t, u) : c.track->at(u);
            };
            s = ray_light_to_segment(scene, l, J.at, J.length, camera_tr, radius_, phase_aware_, c.min_distance2, rng,
                                     ms);
        } else {
            s = ray_light_to_point(scene, l, J.at, radius_, phase_aware_, c.min_distance2, rng, ms);
        }
        const RGB value = J.weight * s.value * c.share;
        if (is_black(value) || !std::isfinite(value.x + value.y + value.z)) return;
        VirtualLight y;  // the ray light's point, as a medium light for the shadow ray
        y.kind = VirtualLightKind::Medium;
        y.pos = s.y;
        y.axis = -l.dir;
        y.medium = l.medium;
        GatherPoint at = J.at;
        at.pos = s.x;
        aim_at_virtual_light(scene, r, at, y, s.w);
        r.contribution = value;
        r.rng = rng.fork();
        r.live = true;
    }

private:
    RadiusSchedule schedule_;
    double radius_ = 0;
    bool phase_aware_ = false;
    std::vector<RayLight> rays_;
};

}  // namespace pgi
