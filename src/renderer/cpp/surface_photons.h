// Surface density estimation (Jensen 1996), shared by pm / sppm and ppb: the
// photons near a diffuse surface point that belong to that surface.
#pragma once

#include <vector>

#include "subpaths.h"
#include "photon_map.h"

namespace pgi {

// A photon counts at x only if its surface faces about the same way (cos > 0.5):
// photons on a perpendicular wall near a corner, or across a thin wall, are
// another surface's.
constexpr double kPhotonNormalAgreement = 0.5;

// Whether photon ph belongs to the surface of triangle T (the two rules above).
inline bool surface_photon_counts(const Scene &scene, const Triangle &T, const PathVertex &ph) {
    return dot(scene.triangles[ph.triangle].n, T.n) >= kPhotonNormalAgreement && dot(ph.wi, T.n) > 0;
}

// Sum of the powers of the photons within `radius` of x on diffuse triangle `tri`
// that lie on a surface facing the same way and arrived from its front, times
// the diffuse BSDF (reflectance / pi); the caller divides by the kernel's area.
// `counts(photon)` applies the method's own depth rule. Zero when wo (towards
// the viewer) is behind the one-sided surface.
template <typename Counts>
RGB reflected_photon_power(const Scene &scene, const PointTree &tree, const std::vector<PathVertex> &photons,
                           int tri, const Vec3 &x, const Vec3 &wo, double radius, Counts &&counts) {
    const Triangle &T = scene.triangles[tri];
    RGB sum(0.0);
    if (dot(wo, T.n) <= 0) return sum;
    tree.query_sphere(x, radius, [&](size_t i, double) {
        const PathVertex &ph = photons[i];
        if (!surface_photon_counts(scene, T, ph) || !counts(ph)) return;
        sum += ph.throughput;
    });
    return sum * scene.materials[T.material].reflectance * kInvPi;
}

// The pilot's query for the same estimate (pilot.h): the distance within which the k nearest
// photons reflected_photon_power would sum at x lie (kInf: fewer than k within max_radius), or
// `none` where it makes no estimate (wo behind the one-sided surface).
template <typename Counts>
double kth_nearest_surface_photon(const Scene &scene, const PointTree &tree, const std::vector<PathVertex> &photons,
                                  int tri, const Vec3 &x, const Vec3 &wo, size_t k, double max_radius,
                                  double none, Counts &&counts) {
    const Triangle &T = scene.triangles[size_t(tri)];
    if (dot(wo, T.n) <= 0) return none;
    return tree.kth_nearest_to_point(x, k, max_radius, [&](uint32_t i) {
        const PathVertex &ph = photons[i];
        return surface_photon_counts(scene, T, ph) && counts(ph);
    });
}

}  // namespace pgi
