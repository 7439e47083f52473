// lt: light tracing (particle tracing to the camera).
//   Veach 1997, "Robust Monte Carlo methods for light transport simulation", ch. 10;
//   Arvo & Kirk 1990, "Particle transport and image synthesis".
//
// Each iteration traces N light paths (subpaths.h) and connects every
// recorded vertex -- including the emission point of area lights, so that
// directly visible emitters are counted once, by this path -- to the pinhole
// camera. Connections cross null boundaries and media through the ShadowQueue
// (transmittance on the way). Each connection is a splat record; the records
// are added to the film in vertex order after all connections are resolved,
// so the image does not depend on the thread count.
//
// Camera importance (pinhole, box filter, Mitsuba's perspective camera): a pixel's
// value is the mean radiance over its footprint on the image plane at distance 1,
//   I_j = 1/A_pix * integral over the pixel of L(p) dp,  A_pix = A_film / (W H),
// where A_film = (2 tan(fov_x/2)) (2 tan(fov_y/2)). A point p of that plane at
// angle theta from the axis has dp = dw / cos^3(theta), so with the measurement
// I_j = integral We(w) L(w) cos(theta) dw the importance is
//   We(w) = 1 / (A_pix cos^4(theta))   inside pixel j (0 elsewhere),
// and a vertex x at distance d contributes power * f * We * cos(theta) / d^2 * Tr / N
//   = power * f * Tr / (N A_pix cos^3(theta) d^2).
// Paths that reach the camera through a specular surface (camera -> glass ->
// ...) cannot be connected by a pinhole and are missing from lt's image.
#pragma once

#include <memory>

#include "subpaths.h"

namespace pgi {

struct CameraConnection {
    Vec3 to_camera;          // unit, from the vertex towards the camera
    double distance = 0;
    int64_t pixel = 0;
    double importance = 0;   // We(w) cos(theta) / d^2 = 1 / (A_pix cos^3 d^2)
    bool valid = false;
};

// Where x projects on the film and how much importance reaches it (see above).
inline CameraConnection connect_to_camera(const Camera &cam, const Vec3 &x) {
    CameraConnection c;
    Vec3 d = cam.origin - x;
    double dist = length(d);
    if (!(dist > 0)) return c;
    Vec3 from_camera = -d / dist;
    double cos_theta = dot(from_camera, cam.forward);
    if (cos_theta <= 0) return c;
    Vec3 q = from_camera / cos_theta;  // on the image plane at distance 1
    double rr = dot(cam.right, cam.right), uu = dot(cam.up, cam.up);
    double sx = dot(q, cam.right) / rr, sy = -dot(q, cam.up) / uu;
    if (!(sx >= -1 && sx < 1 && sy >= -1 && sy < 1)) return c;
    int px = std::min(cam.width - 1, int((sx + 1) * 0.5 * cam.width));
    int py = std::min(cam.height - 1, int((sy + 1) * 0.5 * cam.height));
    double pixel_area = 4 * std::sqrt(rr * uu) / (double(cam.width) * cam.height);
    c.to_camera = -from_camera;
    c.distance = dist;
    c.pixel = int64_t(py) * cam.width + px;
    c.importance = 1 / (pixel_area * cos_theta * cos_theta * cos_theta * dist * dist);
    c.valid = true;
    return c;
}

struct Splat {
    int64_t pixel = -1;
    RGB value{0.0};
};

class LightTracing : public SingleLane<LightTracing>, public NoExtensionRays {
public:
    LightTracing(std::shared_ptr<const Scene> scene, std::shared_ptr<const LightPaths> light_paths, uint64_t seed,
                 int threads);

    // Pass 1: one connection ray per vertex of this iteration's light paths (traced first).
    void begin(int64_t iteration);
    // Pass 2 (repeated): pending connection segments into `out`; returns their count.
    size_t shadow_slots() const { return shadow_.opened(); }
    size_t shadow_rays(const RayBuffers &out);
    void resolve_shadows(const Hits &hits);
    // Pass 3: splats added to the film in vertex order.
    void end();

    const Film &film() const { return film_; }
    const Scene &scene() const { return *scene_; }
    uint64_t density_lookups() const { return stats_.density_lookups; }
    uint64_t light_paths() const { return light_paths_traced_; }

private:
    std::shared_ptr<const Scene> scene_;
    std::shared_ptr<const LightPaths> light_paths_;
    uint64_t seed_;
    int threads_;
    ShadowQueue shadow_;
    std::vector<Splat> splats_;
    Film film_;
    MediumStats stats_;
    uint64_t light_paths_traced_ = 0;
};

}  // namespace pgi
