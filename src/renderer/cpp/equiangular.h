// Sampling a point on a segment of a ray for a light that sits off it, with the sample's density:
//   equi-angular sampling about a point (Kulla & Fajardo 2012, "Importance sampling techniques
//   for path tracing in participating media", EGSR, sec. 4.1), and the truncated exponential
//   (free-flight) distance, its usual partner in MIS.
//
// Equi-angular. The segment x(t) = o + t d, t in [t0, t1] (d unit, t1 may be infinite), and a
// point c off it: t_c = (c - o).d is the closest approach, h = |c - x(t_c)| the distance of c
// from the ray's line. Seen from c, the point x(t) lies at angle theta(t) = atan((t - t_c) / h)
// from the perpendicular; taking theta uniform on [theta_0, theta_1], the ends' angles, gives
//   t = t_c + h tan(theta),   p(t) = h / ((theta_1 - theta_0) (h^2 + (t - t_c)^2))
// that is p(t) = h / ((theta_1 - theta_0) |x(t) - c|^2): the density follows the 1 / distance^2
// of a point light, so an integrand g(t) / |x(t) - c|^2 is estimated by
//   g(t) (theta_1 - theta_0) / h,
// bounded wherever g is, and growing only as 1 / h (equiangular_weight). A centre on the ray's
// line (h = 0) has no such density: the sampler reports it invalid and its callers skip it (a set
// of measure zero).
//
// Truncated exponential on [0, t1] at rate sigma (the free flight of a homogeneous medium,
// conditioned on a collision before t1):
//   p(t) = sigma exp(-sigma t) / (1 - exp(-sigma t1)),   t = -log(1 - u (1 - exp(-sigma t1))) / sigma.
#pragma once

#include <cmath>

#include "common.h"

namespace pgi {

struct EquiAngular {
    double t_closest = 0;  // parameter of the point of the line nearest the centre
    double h = 0;          // the centre's distance from the line
    double tan0 = 0;       // tan(theta_0) = (t0 - t_closest) / h
    double angle = 0;      // theta_1 - theta_0, the angle the segment subtends at the centre
    double t0 = 0, t1 = 0;
    bool valid = false;
    double range() const { return angle; }
};

// The equi-angular distribution on [t0, t1] of the ray (o, d) about `centre`. `soften` > 0 (vbl's
// beams, ray_lights.h) draws as if the centre stood sqrt(h^2 + soften^2) off the line: the density
// then follows 1 / (|x(t) - c|^2 + soften^2), and exists for a centre on the line too.
inline EquiAngular equiangular(const Vec3 &o, const Vec3 &d, double t0, double t1, const Vec3 &centre,
                               double soften = 0) {
    EquiAngular e;
    const Vec3 to_centre = centre - o;
    e.t_closest = dot(to_centre, d);
    const Vec3 off = to_centre - d * e.t_closest;
    e.h = soften > 0 ? std::sqrt(dot(off, off) + soften * soften) : length(off);
    e.t0 = t0;
    e.t1 = t1;
    if (!(e.h > 0) || !std::isfinite(e.h) || !(t1 > t0)) return e;
    const double a = t0 - e.t_closest, b = t1 - e.t_closest;
    e.tan0 = a / e.h;
    // The angle between the centre's views of the two ends, (a, -h) and (b, -h): one atan2
    // instead of two atans; with an infinite end, the angle to the ray's direction.
    e.angle = std::isfinite(b) ? std::atan2(e.h * (b - a), a * b + e.h * e.h) : std::atan2(e.h, a);
    e.valid = e.angle > 0;
    return e;
}

// The parameter t for a uniform u in [0, 1), within [t0, t1]: tan(theta_0 + phi) with
// phi = u (theta_1 - theta_0), by the addition formula in the form whose denominator,
// cos(theta) / cos(theta_0), stays positive (theta lies within (-pi/2, pi/2)).
inline double equiangular_sample(const EquiAngular &e, double u) {
    const double phi = u * e.angle, sin_phi = std::sin(phi), cos_phi = std::cos(phi);
    const double denominator = cos_phi - e.tan0 * sin_phi;
    const double t = denominator > 0 ? e.t_closest + e.h * (sin_phi + e.tan0 * cos_phi) / denominator : e.t1;
    return std::min(std::max(t, e.t0), e.t1);  // rounding near the ends
}

inline double equiangular_pdf(const EquiAngular &e, double t) {
    if (!e.valid || t < e.t0 || t > e.t1) return 0.0;
    const double s = t - e.t_closest;
    return e.h / (e.range() * (e.h * e.h + s * s));
}

// 1 / (p(t) |x(t) - c|^2): the same for every t, (theta_1 - theta_0) / h.
inline double equiangular_weight(const EquiAngular &e) { return e.range() / e.h; }

// |x(t) - c|^2 p(t) = h / (theta_1 - theta_0), the other way round (for MIS with another density).
inline double equiangular_pdf_times_distance2(const EquiAngular &e) { return e.h / e.range(); }

// Truncated exponential on [0, t1] at rate sigma > 0 (t1 may be infinite).
struct TruncatedExponential {
    double sigma = 0, t1 = 0;
    double mass = 0;  // 1 - exp(-sigma t1): the probability of a collision before t1
    bool valid = false;
};

inline TruncatedExponential truncated_exponential(double sigma, double t1) {
    TruncatedExponential e;
    e.sigma = sigma;
    e.t1 = t1;
    e.mass = std::isfinite(t1) ? -std::expm1(-sigma * t1) : 1.0;
    e.valid = sigma > 0 && std::isfinite(sigma) && t1 > 0 && e.mass > 0;
    return e;
}

inline double truncated_exponential_sample(const TruncatedExponential &e, double u) {
    const double t = -std::log1p(-u * e.mass) / e.sigma;
    return std::min(t, e.t1);
}

inline double truncated_exponential_pdf(const TruncatedExponential &e, double t) {
    if (!e.valid || t < 0 || t > e.t1) return 0.0;
    return e.sigma * std::exp(-e.sigma * t) / e.mass;
}

}  // namespace pgi
