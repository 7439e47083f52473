// Participating media: homogeneous (closed forms) and a density grid with
// majorant and minorant grids traversed by DDA. Free flights are sampled by
// delta tracking (Woodcock et al. 1965) against the per-cell majorant; the
// transmittance estimator is chosen per medium:
//   Delta     track-length estimator: delta tracking, 1 if no real collision;
//   Ratio     ratio tracking (Cramer 1978; Novak et al. 2014, sec. 4.1), with
//             Russian roulette once the weight is below 0.25;
//   Residual  residual ratio tracking (Novak et al. 2014, sec. 4.2): per majorant
//             cell the control extinction is the cell's minimum, its transmittance
//             is taken in closed form and only the residual is ratio tracked;
//   RayMarch  fixed-step ray marching with one random offset per ray (biased:
//             exp of an unbiased optical-depth estimate), the classic baseline;
//             with it free flights are also found by marching (biased too).
#pragma once

#include <vector>

#include "common.h"
#include "phase.h"
#include "rng.h"

namespace pgi {

enum class MediumType : int { Homogeneous = 0, Grid = 1 };
enum class Estimator : int { Delta = 0, Ratio = 1, Residual = 2, RayMarch = 3 };

// Density grid on the unit cube placed by an affine map; trilinear
// interpolation with voxel centres at (i + 0.5) / res and clamped edges, as
// Mitsuba's gridvolume.
struct DensityGrid {
    int nx = 0, ny = 0, nz = 0;
    std::vector<float> values;  // x fastest: values[(z * ny + y) * nx + x]
    double world_to_local[3][4] = {};
    // Majorant grid: each cell bounds the interpolated density over its box.
    int cell = 4;  // voxels per majorant cell along each axis
    int mx = 0, my = 0, mz = 0;
    std::vector<float> majorants;
    // Minorant grid: each cell's lower bound of the interpolated density (the
    // control extinction of residual ratio tracking).
    std::vector<float> minorants;

    Vec3 to_local(const Vec3 &p) const {
        const auto &m = world_to_local;
        return {m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
                m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
                m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]};
    }
    Vec3 dir_to_local(const Vec3 &d) const {
        const auto &m = world_to_local;
        return {m[0][0] * d.x + m[0][1] * d.y + m[0][2] * d.z,
                m[1][0] * d.x + m[1][1] * d.y + m[1][2] * d.z,
                m[2][0] * d.x + m[2][1] * d.y + m[2][2] * d.z};
    }
    // Interpolated density at a point in unit-cube coordinates (0 outside). Each lerp is
    // a + t (b - a), exact where a == b: in a constant cell the density equals the
    // cell's exact majorant, never an ulp above it (ratio tracking's 1 - sigma / maj
    // would turn negative).
    double density_local(const Vec3 &q) const {
        // Written so that NaN fails it too: int(NaN) below would index far out of bounds.
        if (!(q.x >= 0 && q.y >= 0 && q.z >= 0 && q.x <= 1 && q.y <= 1 && q.z <= 1)) return 0;
        double fx = q.x * nx - 0.5, fy = q.y * ny - 0.5, fz = q.z * nz - 0.5;
        double bx = std::floor(fx), by = std::floor(fy), bz = std::floor(fz);
        double tx = fx - bx, ty = fy - by, tz = fz - bz;
        // The lower corner is at least -1 and the upper at most n: clamp each once.
        int x0 = int(bx), y0 = int(by), z0 = int(bz);
        size_t xa = size_t(std::max(x0, 0)), xb = size_t(std::min(x0 + 1, nx - 1));
        size_t ya = size_t(std::max(y0, 0)), yb = size_t(std::min(y0 + 1, ny - 1));
        size_t za = size_t(std::max(z0, 0)), zb = size_t(std::min(z0 + 1, nz - 1));
        const float *v = values.data();
        auto row = [&](size_t y, size_t z) { return v + (z * size_t(ny) + y) * size_t(nx); };
        auto lerp = [](double a, double b, double t) { return a + t * (b - a); };
        const float *r00 = row(ya, za), *r10 = row(yb, za), *r01 = row(ya, zb), *r11 = row(yb, zb);
        double c00 = lerp(r00[xa], r00[xb], tx), c10 = lerp(r10[xa], r10[xb], tx);
        double c01 = lerp(r01[xa], r01[xb], tx), c11 = lerp(r11[xa], r11[xb], tx);
        return lerp(lerp(c00, c10, ty), lerp(c01, c11, ty), tz);
    }
    void build_majorants(int cell_size);
};

struct Medium {
    MediumType type = MediumType::Homogeneous;
    RGB sigma_t{0.0};   // homogeneous: extinction (scale applied); grid: multiplier of density
    RGB albedo{0.0};
    Phase phase;
    DensityGrid grid;  // grid only
    double grid_sigma = 0;  // grid: extinction = grid_sigma * density (gray)
    Estimator estimator = Estimator::Ratio;  // grid: transmittance estimator
    double march_step = 0;  // grid, RayMarch: step length in world units along the ray
    // Homogeneous with the same extinction in every channel: no spectral MIS needed.
    bool gray() const { return sigma_t.x == sigma_t.y && sigma_t.y == sigma_t.z; }
};

// Counts of work done by media estimators, summed per thread.
struct MediumStats {
    uint64_t density_lookups = 0;
    uint64_t segments = 0;  // ray segments tracked through grid media (every estimator)
    MediumStats &operator+=(const MediumStats &o) {
        density_lookups += o.density_lookups;
        segments += o.segments;
        return *this;
    }
};
// Lets OpenMP loops sum per-thread counts: reduction(+ : some_medium_stats).
#pragma omp declare reduction(+ : MediumStats : omp_out += omp_in)

// exp(-sigma * t) per channel, with zero extinction meaning 1 even at t = inf.
inline RGB beer_lambert(const RGB &sigma, double t) {
    if (sigma.x == sigma.y && sigma.y == sigma.z) return RGB(sigma.x > 0 ? std::exp(-sigma.x * t) : 1.0);
    RGB tr;
    for (int c = 0; c < 3; ++c) tr[c] = sigma[c] > 0 ? std::exp(-sigma[c] * t) : 1.0;
    return tr;
}

// Result of sampling a free-flight distance along [0, tmax).
struct FreeFlight {
    bool scattered = false;
    double t = 0;
    RGB weight{1.0};  // throughput factor: sigma_s * Tr / pdf, or Tr / pdf on passing
};

// Visits the majorant cells along the ray (world origin o, unit direction d)
// over [0, tmax), in order: visit(t0, t1, sigma_majorant, sigma_minorant) for
// each, until it returns false.
template <typename Visit>
void traverse_cells(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Visit &&visit) {
    const DensityGrid &g = m.grid;
    Vec3 ol = g.to_local(o), dl = g.dir_to_local(d);
    // Clip to the unit cube. (Not a general slab test such as common.h's ray_meets_box made to
    // return its interval: that cost grid scenes 1.8 % more instructions per pt ray, measured
    // on cbox-grid.)
    double t0 = 0, t1 = tmax;
    for (int a = 0; a < 3; ++a) {
        if (dl[a] == 0) {
            if (ol[a] < 0 || ol[a] > 1) return;
            continue;
        }
        double inv = 1 / dl[a];
        double ta = (0 - ol[a]) * inv, tb = (1 - ol[a]) * inv;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    if (!(t0 < t1)) return;
    // The current cell is one linear index; each axis keeps its signed stride, the
    // boundary crossings left before the ray leaves the grid, and the next crossing's t.
    const int res[3] = {g.mx, g.my, g.mz};
    const int64_t stride_of[3] = {1, g.mx, int64_t(g.mx) * g.my};
    Vec3 p = ol + dl * t0;
    int64_t index = 0, stride[3];
    int crossings_left[3];
    double next_t[3], delta_t[3];
    for (int a = 0; a < 3; ++a) {
        int c = std::clamp(int(std::floor(p[a] * res[a])), 0, res[a] - 1);
        index += c * stride_of[a];
        if (dl[a] > 0) {
            stride[a] = stride_of[a];
            crossings_left[a] = res[a] - 1 - c;
            delta_t[a] = 1 / (dl[a] * res[a]);
            next_t[a] = t0 + (double(c + 1) / res[a] - p[a]) / dl[a];
        } else if (dl[a] < 0) {
            stride[a] = -stride_of[a];
            crossings_left[a] = c;
            delta_t[a] = -1 / (dl[a] * res[a]);
            next_t[a] = t0 + (double(c) / res[a] - p[a]) / dl[a];
        } else {
            stride[a] = 0;
            crossings_left[a] = 0;
            delta_t[a] = kInf;
            next_t[a] = kInf;
        }
    }
    const float *majorants = g.majorants.data(), *minorants = g.minorants.data();
    double t = t0;
    while (t < t1) {
        int a = (next_t[0] < next_t[1]) ? (next_t[0] < next_t[2] ? 0 : 2) : (next_t[1] < next_t[2] ? 1 : 2);
        double t_exit = std::min(next_t[a], t1);
        if (t_exit > t && !visit(t, t_exit, majorants[index] * m.grid_sigma, minorants[index] * m.grid_sigma))
            return;
        t = t_exit;
        if (crossings_left[a]-- == 0) return;
        index += stride[a];
        next_t[a] += delta_t[a];
    }
}

// As traverse_cells, with visit(t0, t1, sigma_majorant).
template <typename Visit>
void traverse_majorants(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Visit &&visit) {
    traverse_cells(m, o, d, tmax, [&](double t0, double t1, double maj, double) { return visit(t0, t1, maj); });
}

// Extinction at a world point of a grid medium.
inline double grid_sigma_t(const Medium &m, const Vec3 &p, MediumStats &stats) {
    ++stats.density_lookups;
    return m.grid_sigma * m.grid.density_local(m.grid.to_local(p));
}

// The optical depth to the next tentative collision, carried across majorant cells:
// one exponential per collision, drawn when first needed, and what is left of it at a
// cell boundary carries into the next cell (memoryless: the remainder is again
// Exp(1)). A cell the flight passes costs a multiply and a compare, not a logarithm.
class CarriedDepth {
public:
    // Moves t in [t, t1), at `rate` > 0, to the next collision (true), or to t1 with the
    // cell's optical depth used up (false).
    bool next_collision(double &t, double t1, double rate, Sampler &rng) {
        if (left_ < 0) left_ = exponential_depth(rng.next());
        double rest = rate * (t1 - t);
        if (left_ < rest) {
            double hit = t + left_ / rate;
            if (hit < t1) {
                t = hit;
                left_ = -1;
                return true;
            }
            left_ = rest;  // rounding put the collision on the cell's end: pass with 0 left
        }
        left_ -= rest;
        t = t1;
        return false;
    }

private:
    double left_ = -1;  // negative: not drawn yet
};

// Tentative collisions over [0, tmax) at each cell's majorant rate. visit(t, maj)
// returns false to stop.
template <typename Visit>
void tentative_collisions(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Sampler &rng,
                          Visit &&visit) {
    CarriedDepth depth;
    traverse_majorants(m, o, d, tmax, [&](double t0, double t1, double maj) {
        if (maj <= 0) return true;
        double t = t0;
        while (depth.next_collision(t, t1, maj, rng))
            if (interrupted() || !visit(t, maj)) return false;
        return true;
    });
}

// Delta tracking over [0, tmax) against the per-cell majorants: the distance of
// the first real collision, or infinity.
inline double delta_track(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Sampler &rng,
                          MediumStats &stats) {
    double hit = kInf;
    tentative_collisions(m, o, d, tmax, rng, [&](double t, double maj) {
        if (rng.next() * maj >= grid_sigma_t(m, o + d * t, stats)) return true;  // null collision
        hit = t;
        return false;
    });
    return hit;
}

// Fixed-step ray marching over [0, tmax): each step [s, s + len) is represented
// by the extinction at s + u * len (one u per ray), which makes the optical depth
// unbiased and everything computed from it biased. Cells with a zero majorant
// are skipped without lookups. step(s, len, sigma) returns false to stop.
template <typename Step>
void ray_march(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Sampler &rng,
               MediumStats &stats, Step &&step) {
    double h = m.march_step > 0 ? m.march_step : kInf;
    double u = rng.next();
    double s = -1;  // start of the current step, set at the first cell
    double end = 0;
    // The end of the marched range is the clip of [0, tmax) to the grid: find it first.
    traverse_majorants(m, o, d, tmax, [&](double t0, double t1, double) {
        if (s < 0) s = t0;
        end = t1;
        return true;
    });
    if (s < 0) return;
    traverse_majorants(m, o, d, tmax, [&](double, double t1, double maj) {
        while (s < end) {
            if (interrupted()) return false;
            double len = std::min(h, end - s);
            double x = s + u * len;
            if (x >= t1) return true;  // the sample point lies in a later cell
            double sigma = maj > 0 ? grid_sigma_t(m, o + d * x, stats) : 0.0;
            if (!step(s, len, sigma)) return false;
            s += len;
        }
        return false;
    });
}

// Path-space spectral MIS for chromatic homogeneous media (Wilkie et al. 2014, "Hero
// wavelength spectral sampling"; Pharr et al., PBRT 4th ed., sec. 14.2): the channel that
// samples every free flight of a path (its hero) is drawn once per path, and `ratio` carries
// each channel's pdf of the path's flights so far, relative to their mean. A flight's
// weight is then f / mean(ratio * pdf): the path's throughput is its contribution over the
// mean of the three channels' path pdfs (the balance heuristic over the hero), bounded by 3
// times what a path sampled with each channel's own pdf would carry. Drawing the hero per
// flight instead (single-sample MIS per flight) bounds each flight's weight but not their
// product: in long walks the densest channel grew a heavy tail (docs/media.md).
struct SpectralMis {
    int hero = 0;
    RGB ratio{1.0};  // channels' path pdfs over their mean (mean 1)
    // Folds one flight's per-channel pdf in; returns the divisor of its weight (0: no channel
    // could have sampled it).
    double fold(const RGB &pdf) {
        double norm = mean(ratio * pdf);
        if (norm > 0) ratio = ratio * pdf / norm;
        return norm;
    }
};

// A path's hero channel, drawn from a child of its stream: drawing it uses up no dimension of
// the path's own (scenes without chromatic media keep their images).
inline int hero_channel(const Sampler &path_rng) {
    return std::min(2, int(path_rng.split(stream_tag::kHero).next() * 3));
}

// Distance sampling. Homogeneous media use the closed form; with chromatic extinction the
// path's SpectralMis picks the channel that samples and carries the pdf ratios (for a path's
// first flight this is single-sample MIS over the channels). Grids use delta tracking against
// the per-cell majorant (extinction is gray there), or marching for the RayMarch estimator.
inline FreeFlight sample_free_flight(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax,
                                     Sampler &rng, MediumStats &stats, SpectralMis &spectral) {
    FreeFlight f;
    if (m.type == MediumType::Homogeneous && m.gray()) {
        // Exact distance sampling: the weight is the albedo on collision, 1 on passing.
        double sig = m.sigma_t.x;
        double t = sig > 0 ? exponential_depth(rng.next()) / sig : kInf;
        if (t < tmax) {
            f.scattered = true;
            f.t = t;
            f.weight = m.albedo;
        }
        return f;
    }
    if (m.type == MediumType::Homogeneous) {
        double sig = m.sigma_t[spectral.hero];
        double t = sig > 0 ? exponential_depth(rng.next()) / sig : kInf;
        if (t < tmax) {
            RGB tr = beer_lambert(m.sigma_t, t);
            double norm = spectral.fold(m.sigma_t * tr);
            f.scattered = true;
            f.t = t;
            f.weight = norm > 0 ? m.sigma_t * m.albedo * tr / norm : RGB(0.0);
        } else {
            RGB tr = beer_lambert(m.sigma_t, tmax);
            double norm = spectral.fold(tr);
            f.weight = norm > 0 ? tr / norm : RGB(0.0);
        }
        return f;
    }
    ++stats.segments;
    if (m.estimator == Estimator::RayMarch) {
        double target = exponential_depth(rng.next()), tau = 0;
        ray_march(m, o, d, tmax, rng, stats, [&](double s, double len, double sigma) {
            // An empty step never scatters, even for a depth target of exactly 0 (u = 0),
            // which would otherwise put the collision at 0 / 0.
            if (sigma <= 0 || tau + sigma * len < target) {
                tau += sigma * len;
                return true;
            }
            f.scattered = true;
            f.t = s + (target - tau) / sigma;
            f.weight = m.albedo;
            return false;
        });
        return f;
    }
    double t = delta_track(m, o, d, tmax, rng, stats);
    if (t < kInf) {
        f.scattered = true;
        f.t = t;
        f.weight = m.albedo;
    }
    return f;
}

// Where a camera segment's medium estimate draws its weight: a free flight along [0, tmax)
// (density sigma_t Tr, the weight of the estimate along the segment; the path's hero channel
// where extinction is chromatic), and the mean free path 1 / sigma_t where it ends (t kInf: the
// flight crosses the segment). The default radii of pm and ppb are measured around [0, t]
// (methods/radii.py): in a dense medium only about a mean free path of the segment counts, and
// a segment through empty parts of a grid estimates nothing.
struct PilotFlight {
    double t = kInf;
    double free_path = 0;
};

inline PilotFlight pilot_flight(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Sampler rng,
                                const Sampler &path_rng) {
    MediumStats stats;
    SpectralMis spectral;
    spectral.hero = hero_channel(path_rng);
    FreeFlight f = sample_free_flight(m, o, d, tmax, rng, stats, spectral);
    PilotFlight out;
    if (!f.scattered) return out;
    double sigma = m.type == MediumType::Homogeneous ? m.sigma_t[spectral.hero] : grid_sigma_t(m, o + d * f.t, stats);
    out.t = f.t;
    out.free_path = sigma > 0 ? 1 / sigma : kInf;
    return out;
}

// Below this weight, ratio tracking plays Russian roulette: survive with
// probability tr / kRouletteTransmittance at weight kRouletteTransmittance, else
// stop at 0 (unbiased; saves the lookups that would refine a negligible value).
// Shadow-ray efficiency 1 / (variance x lookups) on smoke and cbox-grid is flat
// for thresholds 0.2-0.4 and 7-10 % below that at 0.1 (bench/bench_media.py).
constexpr double kRouletteTransmittance = 0.25;

inline bool roulette_transmittance(double &tr, Sampler &rng) {
    if (tr >= kRouletteTransmittance) return true;
    if (tr > 0 && rng.next() * kRouletteTransmittance < tr) {
        tr = kRouletteTransmittance;
        return true;
    }
    tr = 0;
    return false;
}

// Ratio tracking (Cramer 1978; Novak et al. 2014, sec. 4.1) over [0, tmax) in a
// grid: returns the transmittance estimate. on_step(t, tr) sees the running
// product after each tentative collision at t, itself an unbiased estimate of
// Tr(0, t) (the roulette keeps every prefix unbiased).
template <typename OnStep>
double ratio_track(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Sampler &rng, MediumStats &stats,
                   OnStep &&on_step) {
    double tr = 1;
    tentative_collisions(m, o, d, tmax, rng, [&](double t, double maj) {
        tr *= 1 - grid_sigma_t(m, o + d * t, stats) / maj;
        bool go_on = roulette_transmittance(tr, rng);
        on_step(t, tr);
        return go_on;
    });
    return tr;
}

// The integral of the interpolated density over [t0, t1) of the line o + d t (grid-local
// coordinates, inside the unit cube). The density is trilinear between the planes through voxel
// centres, so along a line it is a cubic polynomial between two crossings of those planes, and
// Simpson's rule on each such piece is exact (up to rounding).
inline double integrate_density_local(const DensityGrid &g, const Vec3 &o, const Vec3 &d, double t0, double t1) {
    // Per axis, the next voxel-centre plane u = (k + 0.5) / n the line crosses after t0 and the
    // t it crosses at; the pieces between crossings are visited in order, as a DDA does.
    const int res[3] = {g.nx, g.ny, g.nz};
    double next_t[3], step_t[3];
    for (int a = 0; a < 3; ++a) {
        next_t[a] = step_t[a] = kInf;
        if (d[a] == 0) continue;
        const double k = d[a] > 0 ? std::floor((o[a] + d[a] * t0) * res[a] - 0.5) + 1
                                  : std::ceil((o[a] + d[a] * t0) * res[a] - 0.5) - 1;
        next_t[a] = ((k + 0.5) / res[a] - o[a]) / d[a];
        step_t[a] = 1 / (std::abs(d[a]) * res[a]);
    }
    double sum = 0, t = t0, f_t = g.density_local(o + d * t0);
    while (t < t1) {
        const double b = std::min({next_t[0], next_t[1], next_t[2], t1});
        for (int a = 0; a < 3; ++a)
            if (next_t[a] <= b) {
                const double after = next_t[a] + step_t[a];
                next_t[a] = after > next_t[a] ? after : kInf;  // a step below an ulp of t: done
            }
        if (!(b > t)) continue;
        const double f_b = g.density_local(o + d * b);
        sum += (b - t) / 6 * (f_t + 4 * g.density_local(o + d * (0.5 * (t + b))) + f_b);
        t = b;
        f_t = f_b;
    }
    return sum;
}

// The deterministic stand-ins for free-flight probabilities that path densities use
// (path_records.h): the extinction at x, and the optical depth of [0, length) along (o, d).
// Homogeneous media: the mean of the channels' extinction (exact for grey media). Grids: the
// grid's extinction at x and the exact optical depth of the interpolated density (constant
// majorant cells in closed form, the others piece by piece between voxel-centre planes). A
// cruder stand-in (the mean of each cell's majorant and minorant) was off by e^10 at a cloud's
// edge, where cells hold both dense core and vacuum, and MIS weights built on it gave bdpt
// five times pt's noise in the cloud.
inline double flight_sigma(const Medium &m, const Vec3 &x, MediumStats &stats) {
    return m.type == MediumType::Homogeneous ? mean(m.sigma_t) : grid_sigma_t(m, x, stats);
}
inline double flight_depth(const Medium &m, const Vec3 &o, const Vec3 &d, double length) {
    if (m.type == MediumType::Homogeneous) {
        const double sigma = mean(m.sigma_t);
        return sigma > 0 ? sigma * length : 0.0;  // no extinction: 0, even over an infinite length
    }
    const DensityGrid &g = m.grid;
    const Vec3 ol = g.to_local(o), dl = g.dir_to_local(d);
    double tau = 0;
    traverse_cells(m, o, d, length, [&](double t0, double t1, double maj, double minor) {
        if (maj <= minor)
            tau += maj * (t1 - t0);  // constant cell (or empty)
        else
            tau += m.grid_sigma * integrate_density_local(g, ol, dl, t0, t1);
        return true;
    });
    return tau;
}

// Transmittance over [0, tmax): closed form in homogeneous media, the medium's
// estimator in grids.
inline RGB transmittance(const Medium &m, const Vec3 &o, const Vec3 &d, double tmax, Sampler &rng,
                         MediumStats &stats) {
    if (m.type == MediumType::Homogeneous) {
        return beer_lambert(m.sigma_t, tmax);
    }
    ++stats.segments;
    double tr = 1;
    switch (m.estimator) {
        case Estimator::Delta:
            return RGB(delta_track(m, o, d, tmax, rng, stats) < kInf ? 0.0 : 1.0);
        case Estimator::RayMarch: {
            double tau = 0;
            ray_march(m, o, d, tmax, rng, stats, [&](double, double len, double sigma) {
                tau += sigma * len;
                return true;
            });
            return RGB(std::exp(-tau));
        }
        case Estimator::Residual: {
            CarriedDepth depth;  // of the residual rate
            traverse_cells(m, o, d, tmax, [&](double t0, double t1, double maj, double minor) {
                if (maj <= 0) return true;
                tr *= std::exp(-minor * (t1 - t0));  // the control, in closed form
                double residual = maj - minor;
                if (!(residual > 0)) return true;  // constant cell: the control is exact
                // Before this cell's lookups, not after the control: constant cells stay exact.
                if (!roulette_transmittance(tr, rng)) return false;
                double t = t0;
                while (depth.next_collision(t, t1, residual, rng)) {
                    if (interrupted()) return false;
                    // (sigma - minor) / residual is the residual's null-collision ratio.
                    tr *= std::max(0.0, maj - grid_sigma_t(m, o + d * t, stats)) / residual;
                    if (!roulette_transmittance(tr, rng)) return false;
                }
                return true;
            });
            return RGB(tr);
        }
        default:
            return RGB(ratio_track(m, o, d, tmax, rng, stats, [](double, double) {}));
    }
}

}  // namespace pgi
