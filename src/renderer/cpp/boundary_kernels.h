// Density-estimation kernels along a camera segment that do not reach across the medium's
// boundary (pm's and sppm's beam radiance estimate, ppb's beam x beam estimate).
//
// The usual kernels lie across the camera ray: a disc of radius r perpendicular to it (the
// beam radiance estimate, Jarosz, Zwicker & Jensen 2008) or a blur of half-width r along the
// common perpendicular of the ray and a beam (BB1D, Jarosz, Nowrouzezahrai, Sadeghi & Jensen
// 2011). Near the surface a segment enters or leaves its medium through, such a kernel reaches
// past the surface whenever the ray is not perpendicular to it, where there are no photons or
// beams, and the estimate loses light: in a slab of fog 1 unit thick seen 5-7 degrees off its
// normal with r = 14 (the old default in a slab 1000 wide), pm kept 0.51-0.81 of the light.
//
// Any kernel centred at each point x(t) of the segment and integrating to 1 gives a consistent
// estimate (its bias vanishes with r): each t may have a kernel of its own. So near a boundary
// plane, where the usual kernel would cross it, the kernel turns parallel to the plane instead:
//   - pm: a disc of radius r in the plane through x(t) parallel to the boundary. A photon at p
//     counts at the t where that plane passes through p, t* = (p - o).n / (d.n), if it lies
//     within r of x(t*), with the weight 1 / (pi r^2 |d.n|) (the Jacobian of t -> the plane's
//     offset) in place of 1 / (pi r^2);
//   - ppb: a blur along b, the common perpendicular m projected on the plane; the beam
//     translated by u b meets the ray at t(u) with the beam at s(u), and a pair counts if
//     |u| < r, with the weight 1 / (2 r sin(theta) (m.b)) in place of 1 / (2 r sin(theta)).
// Where the usual kernel at x(t) reaches the plane: the disc and the blur both reach r sin(phi)
// out of their point along the plane's normal (phi: the angle between ray and normal), and
// x(t) lies t |cos(phi)| from the entry plane, so for t < r tan(phi) (the *entry zone*); the
// same from the exit plane backwards (the *exit zone*). Each zone takes at most half the
// segment. A slab is then exact at any radius (the kernel never leaves it and never mixes
// depths); a curved boundary is planar within a kernel as r shrinks. Rays within 60 degrees
// of grazing a boundary (|cos(phi)| < kMinAlignedCosine) keep the usual kernel there: the
// aligned weight 1 / |cos(phi)| would raise the variance more than the bias it removes.
// The boundary planes are those of the triangles the segment starts on (the surface the path
// left: a null boundary, glass, a diffuse surface) and ends on (its hit); a segment starting at
// the camera, or ending in the medium or at infinity, has no plane at that end.
#pragma once

#include <algorithm>
#include <cmath>

#include "common.h"
#include "scene.h"

namespace pgi {

constexpr double kMinAlignedCosine = 0.5;

struct BoundaryPlane {
    Vec3 normal;        // unit
    double cosine = 0;  // |d . normal| of the segment's direction d
    bool present = false;
};

// The planes at the ends of the segment o + t d, t in [0, tmax], and the zones where the kernel
// lies in them: [0, entry_end) and [exit_start, tmax].
struct KernelZones {
    BoundaryPlane entry, exit;
    double entry_end = 0, exit_start = 0, tmax = 0;

    // Candidates for the aligned zones lie up to r beyond the zones along the ray: a query
    // over [lo(r), hi(r)] finds them all.
    double lo(double r) const { return entry_end > 0 ? -r : 0.0; }
    double hi(double r) const { return exit_start < tmax ? tmax + r : tmax; }
};

// A plane that bounds the segment: the triangle's, if the segment is steep enough to it.
inline BoundaryPlane boundary_plane(const Vec3 &normal, const Vec3 &d) {
    BoundaryPlane b;
    b.normal = normal;
    b.cosine = std::abs(dot(d, normal));
    b.present = b.cosine >= kMinAlignedCosine;
    return b;
}

// The plane of triangle `tri` (a segment's start or end), none for -1 (the camera, or no hit).
inline BoundaryPlane triangle_plane(const Scene &scene, int tri, const Vec3 &d) {
    if (tri < 0) return {};
    return boundary_plane(scene.triangles[size_t(tri)].n, d);
}

// Zones of the segment (unit d, length tmax, which may be infinite) for kernels of radius r,
// with the planes it starts and ends on (absent planes: none).
inline KernelZones kernel_zones(const Vec3 &d, double tmax, double r, const BoundaryPlane &entry,
                                const BoundaryPlane &exit) {
    KernelZones z;
    z.entry = entry;
    z.exit = std::isfinite(tmax) ? exit : BoundaryPlane{};
    z.tmax = tmax;
    z.exit_start = tmax;
    // The usual kernel at x(t) reaches the plane while t |cos| < r sin: t < r tan(phi).
    auto reach = [r](const BoundaryPlane &b) {
        return b.present ? r * std::sqrt(std::max(0.0, 1 - b.cosine * b.cosine)) / b.cosine : 0.0;
    };
    double half = std::isfinite(tmax) ? 0.5 * tmax : kInf;
    z.entry_end = std::min(reach(z.entry), half);
    if (z.exit.present) z.exit_start = tmax - std::min(reach(z.exit), half);
    return z;
}

}  // namespace pgi
