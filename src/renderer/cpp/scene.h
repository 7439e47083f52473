// The scene as the kernels see it: triangles (the same ones Embree traces),
// materials, media, lights and the camera. Built once from Python.
#pragma once

#include <string>
#include <vector>

#include "bsdf.h"
#include "common.h"
#include "medium.h"
#include "rng.h"
#include "sampling.h"

namespace pgi {

struct Triangle {
    Vec3 p0, e1, e2, n;  // n: unit geometric normal, cross(e1, e2) direction
    double area = 0;
    int material = 0;
    int emitter = -1;   // index into Scene::area_emitters, or -1
    int interior = -1;  // medium behind the normal, -1 = vacuum
    int exterior = -1;  // medium on the normal side
    bool transition = false;  // has an interior or exterior medium (else media pass it unchanged)
    Vec3 point(double b1, double b2) const { return p0 + e1 * b1 + e2 * b2; }
    // Medium a ray in medium `current` is in after leaving this surface in
    // direction d. As in Mitsuba, only shapes that name a medium change it.
    int medium_after(int current, const Vec3 &d) const {
        if (!transition) return current;
        return dot(d, n) > 0 ? exterior : interior;
    }
};

enum class LightType : int { Area = 0, Point = 1, Spot = 2, Directional = 3 };

// The Russian roulette every path plays after rr_depth real events (wavefront.h,
// survive_roulette): survival from its throughput (the default), or Mitsuba's capped rule.
enum class Roulette : int { Throughput = 0, Mitsuba = 1 };

struct AreaEmitter {
    RGB radiance;
    std::vector<int> triangles;
    Distribution1D by_area;
    double area = 0;
};

struct Light {
    LightType type = LightType::Point;
    int emitter = -1;  // area lights: index into area_emitters
    Vec3 position;
    Vec3 direction;    // spot axis / directional travel direction
    RGB intensity;     // point/spot: W/sr; directional: irradiance
    double cos_cutoff = 0, cutoff = 0, beam_width = 0, cos_beam = 1;
    // Spot falloff as Mitsuba: 1 inside beam_width, linear in angle to 0 at cutoff.
    double spot_falloff(const Vec3 &w) const {
        double c = dot(w, direction);
        if (c <= cos_cutoff) return 0;
        if (c >= cos_beam) return 1;
        return std::clamp((cutoff - std::acos(std::min(1.0, c))) / (cutoff - beam_width), 0.0, 1.0);
    }
};

struct LightSample {
    Vec3 point;       // on the light (finite lights)
    Vec3 wi;          // from the shading point towards the light
    double dist = 0;  // to the light point (infinite for directional)
    RGB value{0.0};   // emitted radiance / pdf, including the selection probability
    double pdf = 0;   // solid-angle pdf (for MIS); 0 for delta lights
    int light = -1;     // the light picked (-1: none)
    int triangle = -1;  // area lights: the triangle sampled
    bool delta = false;
    bool valid = false;
};

struct Camera {
    Vec3 origin, forward, right, up;  // right/up scaled by the half-extents at distance 1
    int width = 0, height = 0;
    int medium = -1;
    // World direction through film position (fx, fy) in pixels, (0,0) top-left.
    Vec3 direction(double fx, double fy) const {
        double sx = 2 * fx / width - 1, sy = 2 * fy / height - 1;
        return normalize(forward + right * sx - up * sy);
    }
};

// The start of a ray that leaves a surface. Its origin lies an offset off the surface;
// `lead` is the length of the ray's line between the surface and that origin. A medium on
// that side fills the lead too, and media estimators add it back: skipping it would lose
// the light of a sliver of medium at every surface and boundary a ray leaves, which in a
// dense medium, or far from the scene's origin where offsets grow, darkens the image.
struct RayStart {
    Vec3 origin;
    double lead = 0;
};
// Grazing rays take the lead of this cosine: the surface there is beside the ray, not
// behind it, and a longer lead could reach past the triangle's edge.
constexpr double kMinLeadCosine = 0.1;

class Scene {
public:
    std::vector<Triangle> triangles;
    std::vector<Material> materials;
    std::vector<Medium> media;
    std::vector<AreaEmitter> area_emitters;
    std::vector<Light> lights;
    Distribution1D light_selection;  // by approximate power
    Camera camera;
    Roulette roulette = Roulette::Throughput;  // the scene's integrator.rr
    double ray_epsilon = 1e-5;  // surface offset, relative to the scene's size
    double scene_radius = 1;
    Vec3 scene_center;

    // The disk a directional light's paths start on, perpendicular to its (unit) direction of
    // travel: radius 1.01 scene radii, centred as far before the scene's centre, so that it
    // covers the bounding sphere from just outside it.
    struct Disk {
        Vec3 centre;
        double radius;
    };
    Disk directional_disk(const Vec3 &direction) const {
        const double radius = scene_radius * 1.01;
        return {scene_center - direction * radius, radius};
    }
    // Some triangle is a null (index-matched) boundary that paths and shadow rays cross.
    // Starts true so that a scene not yet finalized never lets shadow rays skip a boundary.
    bool has_null_surfaces = true;

    void finalize();

    // The medium each light emits into (-1: vacuum), decided once by the scene's rule
    // (docs/scene-format.md, "Where lights emit"; renderer/engine.py) and set from Python:
    // per light (point, spot and directional lights read it) and per triangle (emitting
    // triangles that name no medium read it; those that name one emit into their exterior).
    void set_emission_media(std::vector<int> per_triangle, std::vector<int> per_light);
    int light_emission_medium(int light) const { return light_emission_medium_[size_t(light)]; }
    int triangle_emission_medium(int tri) const { return triangle_emission_medium_[size_t(tri)]; }

    // The medium where the straight walk from the camera to p ends: it starts in the camera's
    // medium and applies Triangle::medium_after at every crossing of a triangle that names a
    // medium, nearest first (ties: lower triangle index first), the rule every ray follows.
    // Brute force in double precision with edges inclusive: a crossing through an edge that
    // two triangles share is counted on both, which the absolute transition rule makes
    // harmless. Deterministic, for the few points a scene asks about.
    int walk_medium(const Vec3 &p) const;

    // Where a ray leaving point p of triangle `tri` in direction d starts: an offset off the
    // surface, on d's side, so that Embree does not find the surface again.
    RayStart spawn(const Vec3 &p, int tri, const Vec3 &d) const {
        const Vec3 &n = triangles[tri].n;
        const double eps = offset_length(p), cos_d = dot(d, n);
        return {p + n * (cos_d > 0 ? eps : -eps), eps / std::max(std::abs(cos_d), kMinLeadCosine)};
    }
    double offset_length(const Vec3 &p) const {
        return ray_epsilon * (1 + max_abs_component(p) / scene_radius);
    }
    // How far from a light at p connections stop and light paths start: two offsets, so that
    // a light on a surface (a lamp set into the ceiling) is reached and leaves it alike.
    double light_clearance(const Vec3 &p) const { return 2 * offset_length(p); }

    LightSample sample_light(const Vec3 &p, Sampler &rng) const {
        const double u0 = rng.next(), u1 = rng.next(), u2 = rng.next(), u3 = rng.next();
        return sample_light(p, u0, u1, u2, u3);
    }
    // The same from given uniforms: u_pick picks the light, u1 the triangle of an area
    // light and (u2, u3) the point on it.
    LightSample sample_light(const Vec3 &p, double u_pick, double u1, double u2, double u3) const;
    // Solid-angle pdf that sample_light would pick direction from `from` to the
    // point `hit` on emissive triangle `tri`.
    double area_light_pdf(int tri, const Vec3 &from, const Vec3 &hit) const;
    // The light index of area emitter `emitter`.
    int light_of_emitter(int emitter) const { return light_of_emitter_[size_t(emitter)]; }
    // Radiance leaving triangle `tri` towards -d (one-sided).
    RGB emitted(int tri, const Vec3 &d) const {
        const Triangle &t = triangles[tri];
        if (t.emitter < 0 || dot(d, t.n) >= 0) return RGB(0.0);
        return area_emitters[t.emitter].radiance;
    }

private:
    std::vector<int> light_of_emitter_;
    // Sized by finalize (vacuum) until set_emission_media sets them.
    std::vector<int> light_emission_medium_, triangle_emission_medium_;
};

}  // namespace pgi
