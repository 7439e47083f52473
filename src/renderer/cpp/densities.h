// The densities of subpath vertices (path_records.h) as functions of the recorded path: what a
// vertex needs to give the density of the next one, and of the one before it seen from the
// other side. Shared by the subpath tracers (subpaths.h), which fill pdf_fwd and pdf_rev as
// they walk, and by bidirectional connections (bdpt.h), which compute the densities that a
// connection changes. Every direction and cosine is taken from the recorded positions (rays
// leaving surfaces start offset off them), so that a path's densities are the same whichever
// strategy sampled it.
#pragma once

#include <cstdint>

#include "path_records.h"
#include "scene.h"

namespace pgi {

// How a vertex samples the direction on, and where the density of that direction comes from.
struct DensityVertex {
    enum class Sampling : uint8_t {
        Stored,      // pdf_dir: a mirror's 1, a point or spot light's, a directional light's
                     // disk's area density (the disk's rays are parallel: at_infinity)
        Cosine,      // about `normal`: a diffuse surface, an area light
        Phase,       // the phase function of `medium`
        Dielectric,  // the discrete probability of reflection or refraction (pdf_dir: the ior)
        Camera,      // the pinhole camera: uniform over the film, 1 / (A_film cos^3)
    };
    Vec3 pos;
    Vec3 normal;              // its surface's normal (zero in a medium, at point and
                              // directional lights and at the camera)
    Vec3 wi;                  // unit, towards the vertex before it (zero at a light or camera)
    double pdf_dir = 0;       // see Sampling
    double sigma = 0;         // its extinction, if it lies in a medium
    double tau_in = 0;        // stand-in optical depth of the edge from the vertex before
    int64_t record = -1;      // its index in the vertices of this iteration (-1: none yet)
    int32_t medium = -1;      // Phase: the medium whose phase function samples
    Sampling sampling = Sampling::Stored;
    bool at_infinity = false; // a directional light's: parallel rays, no 1 / distance^2
    bool delta_light = false; // a light's delta position or direction: never sampled back
};

// The pinhole camera's density of sampling direction w: each pixel gets the same number of
// samples, uniform over its footprint, so over the whole film on the image plane at distance 1
// the density is 1 / A_film, that is 1 / (A_film cos^3 theta) per solid angle (0 off the film).
inline double camera_direction_density(const Camera &cam, const Vec3 &w) {
    const double cos_theta = dot(w, cam.forward);
    if (cos_theta <= 0) return 0;
    const Vec3 q = w / cos_theta;  // on the image plane at distance 1
    const double rr = dot(cam.right, cam.right), uu = dot(cam.up, cam.up);
    const double sx = dot(q, cam.right) / rr, sy = dot(q, cam.up) / uu;
    if (!(std::abs(sx) <= 1 && std::abs(sy) <= 1)) return 0;
    const double film_area = 4 * std::sqrt(rr * uu);
    return 1 / (film_area * cos_theta * cos_theta * cos_theta);
}

// Density at v of the direction `out`, for a walk that reached v from direction `back` (unit,
// towards where it came from).
inline double direction_density(const Scene &scene, const DensityVertex &v, const Vec3 &out, const Vec3 &back) {
    switch (v.sampling) {
        case DensityVertex::Sampling::Cosine: return std::max(0.0, dot(v.normal, out)) * kInvPi;
        case DensityVertex::Sampling::Phase: return phase_eval(scene.media[v.medium].phase, back, out);
        case DensityVertex::Sampling::Dielectric: {
            const double cos_in = dot(back, v.normal), eta = cos_in > 0 ? v.pdf_dir : 1 / v.pdf_dir;
            double cos_t;
            const double F = fresnel_dielectric(std::abs(cos_in), eta, cos_t);
            return (dot(out, v.normal) > 0) == (cos_in > 0) ? F : 1 - F;  // reflected : refracted
        }
        case DensityVertex::Sampling::Camera: return camera_direction_density(scene.camera, out);
        default: return v.pdf_dir;
    }
}

// The change of measure at v for a direction `d` through it: |cos| on a surface, at an area
// light or at the camera's plane, the extinction in a medium.
inline double measure_at(const DensityVertex &v, const Vec3 &d) {
    return v.sampling == DensityVertex::Sampling::Phase ? v.sigma : std::abs(dot(v.normal, d));
}

// The density with which a walk at `from` (reached from from.wi) samples `to`, over an edge of
// stand-in optical depth tau: the direction's density, the flight, the change of measure.
inline double vertex_density(const Scene &scene, const DensityVertex &from, const Vec3 &back,
                             const DensityVertex &to, double tau) {
    const Vec3 d = to.pos - from.pos;
    const double d2 = dot(d, d);
    if (!(d2 > 0)) return 0.0;
    const Vec3 out = d / std::sqrt(d2);
    return direction_density(scene, from, out, back) * std::exp(-tau) * measure_at(to, out) /
           (from.at_infinity ? 1.0 : d2);
}

// The light-vertex view of light `light` at `pos` (an area light's point on triangle `tri`):
// how it samples the direction its paths leave in (sample_emission in subpaths.cpp), and the
// area density of its position (with the light's selection; a delta position or direction:
// the selection alone).
inline DensityVertex emitter_density_vertex(const Scene &scene, int light, const Vec3 &pos, int tri,
                                            double &pdf_pos) {
    DensityVertex v;
    v.pos = pos;
    const Light &l = scene.lights[size_t(light)];
    const double pick = scene.light_selection.pmf(size_t(light));
    switch (l.type) {
        case LightType::Area:
            v.sampling = DensityVertex::Sampling::Cosine;
            v.normal = scene.triangles[size_t(tri)].n;
            pdf_pos = pick / scene.area_emitters[size_t(l.emitter)].area;
            return v;
        case LightType::Point: v.pdf_dir = kInv4Pi; break;
        case LightType::Spot: v.pdf_dir = square_to_uniform_cone_pdf(l.cos_cutoff); break;
        case LightType::Directional: {
            const double r = scene.directional_disk(l.direction).radius;
            v.pdf_dir = square_to_uniform_disk_concentric_pdf() / (r * r);  // its disk's area density
            v.at_infinity = true;
            break;
        }
    }
    v.delta_light = true;
    pdf_pos = pick;
    return v;
}

// The density view of a recorded vertex (path_records.h): what its record says of it, with the
// scene's materials, media and lights.
inline DensityVertex density_vertex(const Scene &scene, const PathVertex &r, MediumStats &stats) {
    DensityVertex v;
    switch (r.kind) {
        case VertexKind::Emission: {
            double pdf_pos;
            v = emitter_density_vertex(scene, r.light, r.pos, r.triangle, pdf_pos);
            break;
        }
        case VertexKind::Camera:
            v.sampling = DensityVertex::Sampling::Camera;
            v.normal = normalize(scene.camera.forward);
            break;
        case VertexKind::Medium:
            v.sampling = DensityVertex::Sampling::Phase;
            v.medium = r.medium;
            v.sigma = flight_sigma(scene.media[size_t(r.medium)], r.pos, stats);
            break;
        case VertexKind::Surface: {
            const Triangle &T = scene.triangles[size_t(r.triangle)];
            const Material &mat = scene.materials[size_t(T.material)];
            v.normal = T.n;
            if (mat.type == MaterialType::Diffuse) {
                v.sampling = DensityVertex::Sampling::Cosine;
            } else if (mat.type == MaterialType::Dielectric) {
                v.sampling = DensityVertex::Sampling::Dielectric;
                v.pdf_dir = mat.ior;
            } else {
                v.pdf_dir = 1;  // a mirror reflects with probability 1
            }
            break;
        }
    }
    v.pos = r.pos;
    v.wi = r.wi;
    v.tau_in = r.tau_in;
    return v;
}

}  // namespace pgi
