// Surface scattering: diffuse, ideal mirror, smooth dielectric, null boundary.
// Directions point away from the surface; `n` is the geometric normal. Like
// Mitsuba 3, diffuse and mirror are one-sided: light arriving from behind
// the normal is absorbed.
#pragma once

#include "common.h"
#include "sampling.h"

namespace pgi {

enum class MaterialType : int { Diffuse = 0, Mirror = 1, Dielectric = 2, Null = 3 };

struct Material {
    MaterialType type = MaterialType::Diffuse;
    RGB reflectance{0.5};
    double ior = 1.5;  // interior over exterior
    bool is_delta() const { return type != MaterialType::Diffuse; }
};

struct BsdfSample {
    Vec3 wi;
    RGB weight{0.0};  // f * |cos| / pdf
    double pdf = 0;   // solid angle; meaningless when delta
    double eta = 1;   // relative IOR crossed (for Russian roulette, as Mitsuba)
    bool delta = false;
    bool valid = false;
};

// Unpolarised Fresnel reflectance for a dielectric interface. `cos_i` is
// measured on the side the light arrives from, `eta` = eta_t / eta_i.
// Returns reflectance and the cosine of the transmitted direction (0 on TIR).
inline double fresnel_dielectric(double cos_i, double eta, double &cos_t) {
    double sin2_t = (1 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1) {
        cos_t = 0;
        return 1;
    }
    cos_t = std::sqrt(1 - sin2_t);
    double rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    double rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

// f(wo, wi) * |cos(wi)| for the non-delta part (only diffuse has one).
inline RGB bsdf_eval(const Material &m, const Vec3 &n, const Vec3 &wo, const Vec3 &wi) {
    if (m.type != MaterialType::Diffuse) return RGB(0.0);
    double co = dot(wo, n), ci = dot(wi, n);
    if (co <= 0 || ci <= 0) return RGB(0.0);
    return m.reflectance * (ci * kInvPi);
}

inline double bsdf_pdf(const Material &m, const Vec3 &n, const Vec3 &wo, const Vec3 &wi) {
    if (m.type != MaterialType::Diffuse) return 0;
    double co = dot(wo, n), ci = dot(wi, n);
    if (co <= 0 || ci <= 0) return 0;
    return ci * kInvPi;
}

// Samples wi given wo. `radiance` selects the adjoint scaling of refraction:
// true for camera paths (radiance), false for light paths (importance).
inline BsdfSample bsdf_sample(const Material &m, const Vec3 &n, const Vec3 &wo, double u1, double u2,
                              double u3, bool radiance = true) {
    BsdfSample s;
    double co = dot(wo, n);
    switch (m.type) {
        case MaterialType::Diffuse: {
            if (co <= 0) return s;
            Vec3 local = square_to_cosine_hemisphere(u1, u2);
            if (local.z <= 0) return s;
            s.wi = Frame(n).to_world(local);
            s.pdf = local.z * kInvPi;
            s.weight = m.reflectance;
            s.valid = true;
            return s;
        }
        case MaterialType::Mirror: {
            if (co <= 0) return s;
            s.wi = reflect(wo, n);
            s.weight = RGB(1.0);
            s.delta = s.valid = true;
            return s;
        }
        case MaterialType::Dielectric: {
            bool outside = co > 0;
            double eta = outside ? m.ior : 1.0 / m.ior;  // eta_t / eta_i
            double cos_i = std::abs(co);
            double cos_t;
            double F = fresnel_dielectric(cos_i, eta, cos_t);
            Vec3 nf = outside ? n : -n;  // normal on the side of wo
            s.delta = s.valid = true;
            if (u3 < F) {
                s.wi = reflect(wo, nf);
                s.weight = RGB(1.0);
                s.pdf = F;
            } else {
                s.wi = normalize(nf * (cos_i / eta - cos_t) - wo / eta);
                // Radiance is divided by eta^2 on entering a denser medium.
                s.weight = RGB(radiance ? 1.0 / (eta * eta) : 1.0);
                s.pdf = 1 - F;
                s.eta = eta;
            }
            return s;
        }
        case MaterialType::Null: {
            s.wi = -wo;
            s.weight = RGB(1.0);
            s.delta = s.valid = true;
            return s;
        }
    }
    return s;
}

}  // namespace pgi
