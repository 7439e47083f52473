// vsl: virtual spherical lights in participating media, with a progressively shrinking radius.
//   Hasan, Krivanek, Walter & Bala 2009, "Virtual spherical lights for many-light rendering of
//     glossy scenes" (SIGGRAPH Asia): a light's power spread over a sphere, its integral over
//     the cone the sphere subtends estimated by MIS over cone, BSDF and light-lobe sampling;
//   Knaus & Zwicker 2011, "Progressive photon mapping: a probabilistic approach": the radius
//     schedule;
//   Keller 1997 and Kulla & Fajardo 2012, as vpl (vpl.h: the iteration, the gather jobs, the
//     equi-angular points along camera segments, the coverage).
//
// vpl's estimator (vpl.h) with the point light's transfer F_x(w) F_y(-w) / d^2 replaced by that
// of a light whose power is spread over a sphere of radius r_i about y: the gather point x (on a
// surface, or a point of a camera segment in a medium) sees the sphere's cross-section pi r^2
// as a cone of directions about w_0, the unit direction from x to y, of solid angle
//   Omega = min(4 pi, pi r^2 / d^2),   d = |x - y|   (every direction once d <= r / 2),
// and receives
//   K(x, y) = 1 / (pi r^2) * integral over the cone of F_x(w) F_y(-w) dw.
// In the far field (d >= r / 2) this is F_x F_y / d^2 averaged over the cone: the point light
// exactly wherever F_x F_y is constant across the cone (isotropic phase functions at both
// ends), and to O((r / d)^2) otherwise (first-order variations cancel across the cone). Nearer,
// K stays bounded: 4 F / r^2 at most for a constant F, so a constant F gives vpl's clamped
// 1 / max(d^2, (r / 2)^2). The integral is estimated with one direction from each of three
// strategies, weighted by the balance heuristic (multi-sample MIS):
//   K ~ 1 / (pi r^2) * sum_k 1_cone(w_k) F_x(w_k) F_y(-w_k) / (1 / Omega + p_x(w_k) + p_y(-w_k))
// w_1 uniform in the cone, w_2 from x's lobe (cosine-weighted about a surface's normal, the
// phase function in a medium), w_3 = -(a direction from y's lobe: cosine about a surface's or an
// area light's normal, the phase function in a medium). Visibility and transmittance are those
// of the sphere's centre (one shadow ray x -> y, as vpl's), taken only where the centre lies on
// the lit side of both ends. Point, spot and directional lights are the scene's own delta lights:
// they stay points (vpl.h).
//
// The radius shrinks with the iterations, r_i = r_1 i^(alpha - 1) (i = 1, 2, ...;
// radius_schedule.h with d = 1): as vpl's progressive clamp, the spread's bias is of order r (the
// light within r of a gather point) and its variance grows as 1 / r (1 / d^4 over a volume
// beyond r), so the running mean's MSE falls as n^-min(alpha, 2 (1 - alpha)), n^-2/3 at the
// default alpha = 2/3. The radius is never floored: the image converges to pt's (vpl
// unclamped's) as iterations grow.
#pragma once

#include "vpl.h"

namespace pgi {

// The tag of the stream the sphere's directions come from (a child of the pair's stream, so
// that vsl's other random numbers are vpl's).
constexpr uint64_t kSphereDirections = 0x5370686572650000ull;  // "Sphere"

// K(x, y) above (or, times_d2, d^2 K), from one direction of each strategy drawn from `rng`'s
// child stream. w: unit, x -> y; d2 = |x - y|^2 > 0; r: the sphere's radius.
inline RGB spherical_light_transfer(const Scene &scene, const GatherPoint &x, const VirtualLight &y, const Vec3 &w,
                                    double d2, double r, const Sampler &rng, bool times_d2) {
    const double r2 = r * r;
    const double omega = 4 * d2 <= r2 ? 4 * kPi : kPi * r2 / d2;
    const double one_minus_cos = omega / (2 * kPi);  // of the cone's half-angle, in (0, 2]
    Sampler s = rng.split(kSphereDirections);
    const double u[6] = {s.next(), s.next(), s.next(), s.next(), s.next(), s.next()};
    Vec3 directions[3];
    directions[0] = square_to_uniform_narrow_cone(w, one_minus_cos, u[0], u[1]);
    double unused;
    directions[1] = sample_gather_direction(scene, x, u[2], u[3], unused);
    directions[2] = -sample_virtual_light_lobe(scene, y, u[4], u[5], unused);
    RGB sum(0.0);
    for (int k = 0; k < 3; ++k) {
        const Vec3 &v = directions[k];
        // In the cone: 1 - cos(v, w) = |v - w|^2 / 2 <= 1 - cos(half-angle); the cone's own
        // sample is inside by construction.
        const Vec3 off = v - w;
        if (k > 0 && dot(off, off) > 2 * one_minus_cos) continue;
        const RGB f = gather_scattering(scene, x, v) * virtual_light_emission(scene, y, -v);
        if (is_black(f)) continue;
        const double density =
            1 / omega + gather_direction_pdf(scene, x, v) + virtual_light_lobe_pdf(scene, y, -v);
        sum += f / density;
    }
    return sum * ((times_d2 ? d2 : 1.0) / (kPi * r2));
}

// vsl's transfer from a virtual light to a gather point: K above, with this iteration's radius.
class SphereTransfer {
public:
    void set_radius(double initial, double alpha) { schedule_ = RadiusSchedule(initial, alpha, 1); }
    double radius(int64_t iteration) const { return schedule_.radius(iteration); }
    const RadiusSchedule &schedule() const { return schedule_; }
    void begin(int64_t iteration) { radius_ = radius(iteration); }
    RGB operator()(const Scene &scene, const GatherPoint &x, const VirtualLight &y, const Vec3 &w, double d2,
                   bool times_d2, const Sampler &rng) const {
        return spherical_light_transfer(scene, x, y, w, d2, radius_, rng, times_d2);
    }

private:
    RadiusSchedule schedule_{1.0, 2.0 / 3.0, 1};
    double radius_ = 1;
};

using VirtualSphericalLights = VirtualLightGathering<SphereTransfer>;

}  // namespace pgi
