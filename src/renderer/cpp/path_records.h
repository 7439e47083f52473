// Records of the vertices and medium segments of subpaths, shared by every method that keeps
// its paths: light subpaths today (lt's connections, pm's photons, ppb's beams), camera
// subpaths and bidirectional connections (bdpt), virtual lights (vpl, vsl, vrl, vbl).
//
// Densities (Veach 1997, ch. 10; the `pdfFwd` / `pdfRev` of pbrt's BDPT, the area-measure
// records of SmallUPBP's volumetric BPT). A subpath x_0, x_1, ... is sampled vertex by vertex;
//   pdf_fwd(x_i) = p_dir(x_{i-1} -> x_i) * G(x_{i-1} -> x_i)   the density with which its own
//                                                               path sampled x_i
//   pdf_rev(x_i) = p_dir(x_{i+1} -> x_i) * G(x_{i+1} -> x_i)   the density with which a path
//                                                               coming the other way, through
//                                                               x_{i+1}, would sample it
// with p_dir the solid-angle density of the direction sampled at the vertex (BSDF or phase
// function; the reverse one from the reversed directions), and G the change to the measure of
// x_i: area measure on surfaces, volume measure in media,
//   G(y -> x) = P_flight(y, x) * c(x) / |x - y|^2,   c(x) = |cos| at a surface, 1 in a medium,
//   P_flight  = exp(-tau(y, x)) * (x in a medium ? sigma(x) : 1),
// the probability of a free flight from y to reach x (pass every medium between and, in a
// medium, collide there). tau and sigma are deterministic functions of the path, never a random
// transmittance estimate, so that MIS weights computed from these densities sum to one over
// the strategies that can sample a path: in a homogeneous medium sigma is the mean of the
// channels' extinction and tau = sigma * length (exact for grey media; a grey stand-in for the
// hero-channel spectral MIS of chromatic ones), in a density grid sigma(x) is the grid's
// extinction at x and tau the exact integral of the interpolated density along the segment
// (medium.h, flight_depth): then P_flight is the true free-flight density there too. Null boundaries add no vertex: the
// flight multiplies over the media it crosses.
// Special vertices:
//   - a vertex that scattered by a delta BSDF (`delta`): p_dir is the discrete probability of
//     the event (reflection F, refraction 1 - F, 1 for a mirror), in both directions; MIS
//     skips such vertices (their densities cancel in the strategies that can sample them);
//   - a light vertex (kind Emission): pdf_fwd is the area density of the point sampled on the
//     light (with the light's selection probability); point and spot lights have a delta
//     position (`delta`, pdf_fwd = the selection probability), a directional light a delta
//     direction, and its first vertex's pdf_fwd is the area density on its disk times |cos|
//     (no 1 / distance^2: the disk's rays are parallel);
//   - a camera vertex (kind Camera, the first of a camera subpath): pdf_fwd 1; the camera
//     samples directions uniformly over its film, 1 / (A_film cos^3) per solid angle;
//   - a vertex gets its pdf_rev once two vertices follow it (the density back depends on where
//     the walk through the next one came from); until then, and for the last two vertices of
//     a subpath, it stays 0.
// Densities are filled only when the tracer records complete subpaths (every vertex, delta
// ones included: subpaths.h, set_recording); otherwise pdf_fwd and pdf_rev stay 0.
#pragma once

#include <cstdint>

#include "common.h"

namespace pgi {

enum class VertexKind : uint8_t { Emission = 0, Surface = 1, Medium = 2, Camera = 3 };

// One scattering (or emission) vertex of a subpath.
struct PathVertex {
    Vec3 pos;
    Vec3 wi;                 // unit, from pos towards the previous vertex (emission: the light's
                             // normal, or its direction of travel for a directional light)
    RGB throughput{0.0};     // light subpaths: the flux weight arriving here ("power", below);
                             // camera subpaths: the importance-weighted throughput
    double pdf_fwd = 0;      // densities (above): area measure on surfaces and lights,
    double pdf_rev = 0;      // volume measure in media
    double tau_in = 0;       // the stand-in optical depth of the edge from the vertex before
    int32_t path = 0;        // index of the subpath within its iteration
    int32_t triangle = -1;   // surface and area-light vertices
    int32_t medium = -1;     // medium vertices: the medium; surface: the medium on the side of wi
    int16_t light = -1;      // emission vertices: the light (the core's light index)
    int16_t depth = 0;       // real scattering events up to and including this vertex
    VertexKind kind = VertexKind::Surface;
    bool delta = false;           // scattered by a delta BSDF here; a light's delta position
    bool after_specular = false;  // the previous real event was a delta BSDF (caustic light)
};

// A straight piece of a light subpath inside one medium: a photon beam (ppb) or a ray light
// (vrl, vbl). Depths are stored in 16 bits: the loader keeps min(rr_depth, bounded max_depth)
// <= 10000, and roulette then ends a path of 32767 events with near certainty (subpaths.h).
struct MediumSegment {
    Vec3 origin, dir;        // dir unit
    double length = 0;       // to the sampled collision, or t_surface when none was sampled
    double t_surface = 0;    // to the next surface along dir (kInf when the ray escapes)
    RGB power{0.0};          // flux weight at the origin, before this segment's transmittance
    RGB spectral_ratio{1.0}; // the path's channel pdf ratios at the origin (SpectralMis)
    int32_t path = 0;
    int32_t medium = -1;
    int16_t depth = 0;       // real scattering events before the origin
    bool scattered = false;  // a medium vertex (if in range) follows at origin + dir * length
};

}  // namespace pgi
