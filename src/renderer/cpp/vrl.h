// vrl: virtual ray lights; and vbl (vbl.h), the same kernel with the rays thickened into beams.
//   Novak, Nowrouzezahrai, Dachsbacher & Jarosz 2012, "Virtual ray lights for rendering scenes
//     with participating media", ACM TOG 31(4) (SIGGRAPH);
//   Keller 1997, "Instant radiosity" (the virtual point lights it keeps for surfaces, vpl.h).
//
// One iteration (methods/vrl.py runs the passes):
//   1. LightPaths (subpaths.h) trace N = light_paths paths, recording their non-delta vertices
//      and their medium segments. Every medium segment becomes a ray light (ray_lights.h: a
//      *short* ray light, ending at the collision the tracer sampled on it, or at the surface
//      when none was, flux weight Phi = power / N at its origin, W(v) = Tr / P(pass) along it);
//      every other vertex a virtual point light (virtual_lights.h: area lights' own points,
//      non-delta surface vertices; point, spot and directional lights one each, exact). The
//      medium collisions are *not* point lights: each is a point of a ray light already (the
//      origin of the next segment), and the ray light carries it with its whole segment.
//   2. The gathering kernel of vpl (vpl.h, VirtualLightGathering with RayLights as its extra
//      lights): S = spp_per_iteration camera paths per pixel follow specular chains to their
//      gather jobs (GatherWalk: every medium segment crossed, and the first non-specular
//      surface), and each job joins every light through one shadow ray:
//        point light -> surface point   vpl's transfer, F_x F_y V T / max(d^2, d_i^2) (clamped
//                                       as vpl's, `clamp`; exact lights never);
//        point light -> camera segment  vpl's: one point equi-angular about the light;
//        ray light   -> surface point   one point v on the ray light, equi-angular about x;
//        ray light   -> camera segment  the pair (v, u): v by the density ~ 1 / distance to the
//                                       camera line (Novak et al. 2012, sec. 4.1), u equi-angular
//                                       about y(v) (sec. 4.2); both phase functions, both
//                                       scattering coefficients, Tr along the camera ray (closed
//                                       form or its ratio-tracking walk), W(v) along the ray light,
//                                       the shadow ray's Tr between;
//      the estimators and their weights are written out in ray_lights.h and vpl.h. Lights are
//      shared out among a pixel's S samples as vpl's (interleaved sampling), ray lights among
//      the others.
//   The image is the mean over iterations.
//
// Coverage (docs/methods.md). A path camera -> ... -> x -> y -> ... -> light with x the last
// non-specular camera-side vertex is made once: by joining x to the light-path vertex y (a
// surface vertex or a light's point: a point light; a medium point: a point of a ray light,
// over the whole segment the light path crossed). So the method covers within itself:
//   - single scattering (x on a camera segment, y an area light's point or an exact light) and
//     direct light at surfaces (x a surface point): point lights that are the lights themselves;
//   - multiple scattering with a medium point last on the light side: ray lights (Novak et al.'s
//     subject: two or more scattering events, one of them at y);
//   - light reflected by diffuse surfaces: surface point lights;
//   - emission seen directly or through specular chains: added by the camera walk
//     (GatherWalk); paths whose vertex after x is specular (caustics, single scattering lit
//     through glass): camera paths continue past x in scenes with specular surfaces.
// Unbiased except for the clamp of surface-to-surface point lights (progressive by default,
// vanishing) and of point lights near a camera ray (none: equi-angular sampling).
// Non-finite sample values are dropped before the image (a set of measure zero: a ray light's
// point on the camera line) and skipped pairs are never counted.
#pragma once

#include "ray_lights.h"
#include "vpl.h"

namespace pgi {

using VirtualRayLights = VirtualLightGathering<PointTransfer, RayLights>;

}  // namespace pgi
