// Phase functions. `wo` points back along the incoming ray and `wi` is the
// scattered direction, so forward scattering means wi close to -wo. The
// Henyey-Greenstein g > 0 scatters forward (Henyey & Greenstein 1941).
#pragma once

#include "common.h"
#include "sampling.h"

namespace pgi {

enum class PhaseType : int { Isotropic = 0, HenyeyGreenstein = 1 };

struct Phase {
    PhaseType type = PhaseType::Isotropic;
    double g = 0;
};

// Below this |g| the HG inversion loses precision; isotropic is exact enough.
constexpr double kHgIsotropicLimit = 1e-4;

inline double hg_value(double cos_theta, double g) {
    double denom = 1 + g * g - 2 * g * cos_theta;
    return kInv4Pi * (1 - g * g) / (denom * std::sqrt(denom));
}

// Density of scattering into wi, per steradian; equals the sampling pdf.
inline double phase_eval(const Phase &p, const Vec3 &wo, const Vec3 &wi) {
    if (p.type == PhaseType::Isotropic || std::abs(p.g) < kHgIsotropicLimit) return kInv4Pi;
    return hg_value(-dot(wo, wi), p.g);
}

// Samples wi exactly proportional to the phase function; returns its pdf.
inline Vec3 phase_sample(const Phase &p, const Vec3 &wo, double u1, double u2, double &pdf) {
    if (p.type == PhaseType::Isotropic || std::abs(p.g) < kHgIsotropicLimit) {
        pdf = kInv4Pi;
        return square_to_uniform_sphere(u1, u2);
    }
    double g = p.g;
    double sq = (1 - g * g) / (1 - g + 2 * g * u1);
    double cos_theta = std::clamp((1 + g * g - sq * sq) / (2 * g), -1.0, 1.0);
    Vec3 wi = direction_around(-wo, cos_theta, u2);
    pdf = hg_value(cos_theta, g);
    return wi;
}

}  // namespace pgi
