// Phase functions. `wo` points back along the incoming ray and `wi` is the
// scattered direction, so forward scattering means wi close to -wo, and the
// scattering angle theta has cos(theta) = dot(-wo, wi).
//   Henyey & Greenstein 1941: g > 0 scatters forward.
//   Rayleigh: 3 / (16 pi) (1 + cos^2 theta), sampled by Cardano's formula on its cubic CDF.
//   Tabulated (Mitsuba's `tabphase`): values at cos(theta) regularly spaced on [-1, 1], +1 the
//   forward direction, linearly interpolated and normalised; sampled by exactly inverting the
//   CDF of that piecewise-linear density (a quadratic per interval).
#pragma once

#include <memory>
#include <stdexcept>
#include <vector>

#include "common.h"
#include "sampling.h"

namespace pgi {

enum class PhaseType : int { Isotropic = 0, HenyeyGreenstein = 1, Rayleigh = 2, Tabulated = 3 };

// A piecewise-linear density in mu = cos(theta) on [-1, 1], normalised so that
// 2 pi * integral f(mu) dmu = 1, i.e. f is per steradian.
class PhaseTable {
public:
    explicit PhaseTable(const std::vector<double> &values) {
        if (values.size() < 2) throw std::invalid_argument("tabulated phase: need >= 2 values");
        for (double v : values)
            if (!(v >= 0) || !std::isfinite(v)) throw std::invalid_argument("tabulated phase: values must be finite and >= 0");
        n_ = int(values.size());
        h_ = 2.0 / (n_ - 1);
        cdf_.assign(n_, 0.0);
        for (int i = 1; i < n_; ++i) cdf_[i] = cdf_[i - 1] + 0.5 * h_ * (values[i - 1] + values[i]);
        double total = cdf_.back();
        if (!(total > 0)) throw std::invalid_argument("tabulated phase: values integrate to zero");
        double to_sr = 1.0 / (2 * kPi * total);
        values_.resize(n_);
        for (int i = 0; i < n_; ++i) values_[i] = values[i] * to_sr;
        for (double &c : cdf_) c /= total;  // now the CDF in mu, ending at 1
    }
    // Density per steradian at mu.
    double eval(double mu) const {
        // Not std::clamp, which passes NaN through to int(x) and an out-of-bounds read.
        double x = (mu + 1) / h_;
        x = x >= 0 ? std::min(x, double(n_ - 1)) : 0.0;
        int i = std::min(int(x), n_ - 2);
        double t = x - i;
        return values_[i] * (1 - t) + values_[i + 1] * t;
    }
    // mu with CDF(mu) = u, exactly for the piecewise-linear density.
    double sample(double u) const {
        int i = int(std::upper_bound(cdf_.begin(), cdf_.end(), u) - cdf_.begin()) - 1;
        i = std::clamp(i, 0, n_ - 2);
        // Within the interval the density is f0 + (f1 - f0) t, t in [0, 1]; solve
        // f0 t + (f1 - f0) t^2 / 2 = r in the form that is stable for f1 == f0 and f0 == 0.
        double f0 = values_[i] * 2 * kPi, f1 = values_[i + 1] * 2 * kPi;
        double r = std::max(0.0, (u - cdf_[i]) / h_);
        double disc = std::max(0.0, f0 * f0 + 2 * (f1 - f0) * r);
        double denom = f0 + std::sqrt(disc);
        double t = denom > 0 ? std::clamp(2 * r / denom, 0.0, 1.0) : 0.0;
        return std::clamp(-1 + (i + t) * h_, -1.0, 1.0);
    }
    int size() const { return n_; }

private:
    int n_ = 0;
    double h_ = 0;
    std::vector<double> values_, cdf_;
};

struct Phase {
    PhaseType type = PhaseType::Isotropic;
    double g = 0;
    std::shared_ptr<const PhaseTable> table;  // Tabulated only (absent: isotropic)
};

// Below this |g| the HG inversion loses precision; isotropic is exact enough.
constexpr double kHgIsotropicLimit = 1e-4;

// 1 + g^2 - 2 g cos(theta) as a sum of two non-negative terms, (1 - g)^2 + 2 g (1 - cos)
// for g >= 0 and (1 + g)^2 - 2 g (1 + cos) for g < 0: the plain form cancels to 0 in the
// peak for |g| within ~1e-10 of 1 (an infinite pdf, then NaN MIS weights).
inline double hg_value(double cos_theta, double g) {
    double denom = g >= 0 ? (1 - g) * (1 - g) + 2 * g * (1 - cos_theta)
                          : (1 + g) * (1 + g) - 2 * g * (1 + cos_theta);
    return kInv4Pi * (1 - g) * (1 + g) / (denom * std::sqrt(denom));
}

inline double rayleigh_value(double cos_theta) { return 3.0 / (16.0 * kPi) * (1 + cos_theta * cos_theta); }

// Inverse CDF of the Rayleigh density in mu: mu^3 + 3 mu = 8u - 4 (Cardano), odd in
// 8u - 4, evaluated for the non-negative side to avoid cancellation.
inline double rayleigh_sample_mu(double u) {
    double q = 8 * u - 4;
    double a = std::abs(q) * 0.5;
    double A = std::cbrt(a + std::sqrt(a * a + 1));
    double mu = A - 1 / A;
    return std::clamp(std::copysign(mu, q), -1.0, 1.0);
}

// Density of scattering into wi, per steradian; equals the sampling pdf.
inline double phase_eval(const Phase &p, const Vec3 &wo, const Vec3 &wi) {
    double mu = -dot(wo, wi);
    switch (p.type) {
        case PhaseType::HenyeyGreenstein:
            return std::abs(p.g) < kHgIsotropicLimit ? kInv4Pi : hg_value(mu, p.g);
        case PhaseType::Rayleigh:
            return rayleigh_value(mu);
        case PhaseType::Tabulated:
            return p.table ? p.table->eval(mu) : kInv4Pi;
        default:
            return kInv4Pi;
    }
}

// Samples wi exactly proportional to the phase function; returns its pdf.
inline Vec3 phase_sample(const Phase &p, const Vec3 &wo, double u1, double u2, double &pdf) {
    double mu;
    switch (p.type) {
        case PhaseType::HenyeyGreenstein: {
            if (std::abs(p.g) < kHgIsotropicLimit) {
                pdf = kInv4Pi;
                return square_to_uniform_sphere(u1, u2);
            }
            double g = p.g;
            double sq = (1 - g * g) / (1 - g + 2 * g * u1);
            mu = std::clamp((1 + g * g - sq * sq) / (2 * g), -1.0, 1.0);
            pdf = hg_value(mu, g);
            break;
        }
        case PhaseType::Rayleigh:
            mu = rayleigh_sample_mu(u1);
            pdf = rayleigh_value(mu);
            break;
        case PhaseType::Tabulated:
            if (p.table) {
                mu = p.table->sample(u1);
                pdf = p.table->eval(mu);
                break;
            }
            [[fallthrough]];
        default:
            pdf = kInv4Pi;
            return square_to_uniform_sphere(u1, u2);
    }
    return direction_around(-wo, mu, u2);
}

}  // namespace pgi
