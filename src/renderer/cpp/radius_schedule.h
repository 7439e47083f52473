// Progressive radius schedules for density-estimation methods (sppm, ppb, ...).
//   Knaus & Zwicker 2011, "Progressive photon mapping: a probabilistic approach":
//     r_i = r_1 * i^((alpha - 1) / d),  i = 1, 2, ...  (0-based iteration index here: i = k + 1),
//   with d the dimension of the blur kernel (2: surface photons or the beam radiance
//   estimate, 3: volume points, 1: photon beams) and alpha in (0, 1). This is the closed form
//   of the rate their recursion r_{i+1}^d = r_i^d (i + alpha) / (i + 1) reaches; the
//   recursion's radii are larger by the constant Gamma(1 + alpha)^(-1/d) (5-7 % here), which
//   changes no rate.
// Each iteration is an independent estimate with its own radius; the image is their
// mean. Its variance falls as n^-alpha. Where the radiance is smooth around the query the
// kernel's bias is of order r^2, so it falls as n^(2 (alpha - 1) / d) (squared:
// n^(4 (alpha - 1) / d)) and the MSE as n^-min(alpha, 4 (1 - alpha) / d), at best
// n^(-4 / (d + 4)) for alpha = 4 / (d + 4). Where the kernel straddles an edge, a corner
// or a surface that cuts a beam estimate, the bias is of order r and the MSE there falls
// as n^-min(alpha, 2 (1 - alpha) / d) (pm's measured bias on cbox-fog is of order r^0.9:
// docs/methods.md). alpha = 1 keeps the radius fixed (plain photon mapping: biased, not
// consistent).
#pragma once

#include <cmath>
#include <stdexcept>

namespace pgi {

struct RadiusSchedule {
    double initial = 0;  // r_1, world units
    double alpha = 1;    // in (0, 1]; 1 = constant radius
    int dimension = 2;   // kernel dimension d

    RadiusSchedule() = default;
    RadiusSchedule(double r1, double a, int d) : initial(r1), alpha(a), dimension(d) {
        if (!(r1 > 0)) throw std::invalid_argument("radius schedule: initial radius must be positive");
        if (!(a > 0 && a <= 1)) throw std::invalid_argument("radius schedule: alpha must lie in (0, 1]");
        if (d < 1 || d > 3) throw std::invalid_argument("radius schedule: dimension must be 1, 2 or 3");
    }
    // Radius of iteration k (0-based).
    double radius(int64_t k) const {
        return initial * std::pow(double(k + 1), (alpha - 1) / double(dimension));
    }
    // Exponent of the expected MSE of the running mean after n iterations (n^slope), for a
    // kernel bias of order r^bias_order (2: smooth radiance, 1: at edges).
    double mse_slope(int bias_order = 2) const {
        return -std::min(alpha, 2 * bias_order * (1 - alpha) / double(dimension));
    }
    static double optimal_alpha(int d) { return 4.0 / (d + 4.0); }
};

}  // namespace pgi
