// vbl: progressive virtual beam lights.
//   Novak, Nowrouzezahrai, Dachsbacher & Jarosz 2012, "Progressive virtual beam lights", CGF
//     31(4) (EGSR);
//   Knaus & Zwicker 2011, "Progressive photon mapping: a probabilistic approach" (the argument
//     for the schedule).
//
// vrl's kernel (vrl.h) with its ray lights thickened into beams (RayLights::set_beam_radius):
// the flux of each point y(v) of a ray light spread uniformly over the disc of radius r_i about
// it, perpendicular to the ray light, so that 1 / |x - y|^2 becomes the disc's mean G_r(x, y), in
// closed form, and the two points are drawn with softened densities (ray_lights.h):
//   camera segment:  L_i = beta Phi Tr(c, x) sigma_s(x) f_x W(v) sigma_s(y) f_y V Tr(x, y)
//                          G_r(x, y) / (p_r(v) p_r(u | v))
//   surface point:   L_i = beta Phi f_x W(v) sigma_s(y) f_y V Tr(x, y) G_r(x, y) / p_r(v)
// with p_r the densities of ray_lights.h with h softened to sqrt(h^2 + r^2). Point lights (area
// lights' points, surface vertices, the exact lights) are gathered as in vrl.
//
// The schedule: r_i = r_1 i^(alpha - 1), i = 1, 2, ..., alpha in (0, 1) (radius_schedule.h with
// d = 1), no floor. Why the mean of n iterations converges (Knaus & Zwicker's argument: the
// running mean's MSE is its squared mean bias plus (1 / n^2) sum_i Var_i):
//   - bias: the beam moves flux by at most r_i across the ray light, and G_r - 1 / d^2 =
//     O(r^2 / d^4) where d >> r; integrated over pairs of lines, whose distance h has a density
//     bounded near 0, the bias of iteration i is O(r_i) (O(r_i^2) where no camera ray passes
//     within r of a ray light), so the mean bias is O(n^(alpha - 1)) -> 0;
//   - variance: with r > 0 every factor of a sample's weight that vrl leaves unbounded is bounded
//     by a multiple of 1 / r (the v density's (A_1 - A_0) / sin(theta) <= l / r, the softened
//     equi-angular 1 / sqrt(h_v^2 + r^2) <= 1 / r), and the disc mean's peak at the disc itself
//     is logarithmic (square integrable), so E[sample^2] <= C / r_i and Var_i = O(i^(1 - alpha));
//     (1 / n^2) sum_i Var_i = O(n^-alpha) -> 0.
// So the MSE falls at least as n^-min(alpha, 2 (1 - alpha)) (RadiusSchedule::mse_slope with
// d = 1 and a bias of order r): n^(-2/3) at the default alpha = 2/3, and the limit is vrl's
// unbiased image. The bounds are loose: vrl's own weights grow only like log(1 / h), so the
// variance grows far more slowly than 1 / r as r shrinks (the closing measurements in
// docs/methods.md).
// The point lights' share of the variance is vpl's (its clamp at surfaces; a surface point light
// seen from a camera ray is equi-angular, weight (theta_1 - theta_0) / h, which the beams do not
// soften).
#pragma once

#include "vrl.h"

namespace pgi {

// vbl is VirtualRayLights with a beam radius (set_beam_radius); one kernel class binds both.
using VirtualBeamLights = VirtualRayLights;

}  // namespace pgi
