// Small vector maths shared by every kernel: double precision on the path,
// float32 only in the ray buffers handed to Embree.
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>

namespace pgi {

// Set from Python (renderer.interrupts) when Ctrl-C or SIGTERM arrives while a pass runs
// without the GIL: media tracking, whose cost has no bound in dense media, stops early, and
// the binding raises after the pass (bindings.h, `released`), so no cut-short result is used.
inline std::atomic<bool> g_interrupt{false};  // one for the module (a C++17 inline variable)
inline std::atomic<bool> &interrupt_flag() { return g_interrupt; }
inline bool interrupted() { return g_interrupt.load(std::memory_order_relaxed); }

constexpr double kPi = 3.14159265358979323846;
constexpr double kInvPi = 1.0 / kPi;
constexpr double kInv4Pi = 1.0 / (4.0 * kPi);
constexpr double kInf = std::numeric_limits<double>::infinity();

struct Vec3 {
    double x = 0, y = 0, z = 0;
    Vec3() = default;
    constexpr Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
    explicit constexpr Vec3(double s) : x(s), y(s), z(s) {}
    double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    double &operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
    Vec3 operator+(const Vec3 &b) const { return {x + b.x, y + b.y, z + b.z}; }
    Vec3 operator-(const Vec3 &b) const { return {x - b.x, y - b.y, z - b.z}; }
    Vec3 operator*(const Vec3 &b) const { return {x * b.x, y * b.y, z * b.z}; }
    Vec3 operator/(const Vec3 &b) const { return {x / b.x, y / b.y, z / b.z}; }
    Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
    Vec3 operator/(double s) const {  // one division, three multiplications
        double r = 1.0 / s;
        return {x * r, y * r, z * r};
    }
    Vec3 operator-() const { return {-x, -y, -z}; }
    Vec3 &operator+=(const Vec3 &b) { x += b.x; y += b.y; z += b.z; return *this; }
    Vec3 &operator*=(const Vec3 &b) { x *= b.x; y *= b.y; z *= b.z; return *this; }
    Vec3 &operator*=(double s) { x *= s; y *= s; z *= s; return *this; }
};

using RGB = Vec3;

inline Vec3 operator*(double s, const Vec3 &v) { return v * s; }
inline double dot(const Vec3 &a, const Vec3 &b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(const Vec3 &a, const Vec3 &b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3 &v) { return std::sqrt(dot(v, v)); }
inline Vec3 normalize(const Vec3 &v) { return v / length(v); }
inline double max_component(const Vec3 &v) { return std::max(v.x, std::max(v.y, v.z)); }
inline double mean(const Vec3 &v) { return (v.x + v.y + v.z) / 3.0; }
inline double max_abs_component(const Vec3 &v) {
    return std::max(std::abs(v.x), std::max(std::abs(v.y), std::abs(v.z)));
}
inline Vec3 exp(const Vec3 &v) { return {std::exp(v.x), std::exp(v.y), std::exp(v.z)}; }
inline bool is_black(const RGB &c) { return c.x == 0 && c.y == 0 && c.z == 0; }
inline bool is_finite(const Vec3 &v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
inline Vec3 reflect(const Vec3 &w, const Vec3 &n) { return n * (2.0 * dot(w, n)) - w; }

// Whether the ray o + t d, t in [0, tmax], meets the box [lo - grow, hi + grow]: slab test,
// inv = 1 / d componentwise (a zero component tests the slab directly).
template <typename Scalar>
bool ray_meets_box(const Vec3 &o, const Vec3 &d, const Vec3 &inv, const Scalar lo[3], const Scalar hi[3],
                   double tmax, double grow = 0) {
    double t0 = 0, t1 = tmax;
    for (int a = 0; a < 3; ++a) {
        double l = double(lo[a]) - grow, h = double(hi[a]) + grow;
        if (d[a] == 0) {
            if (o[a] < l || o[a] > h) return false;
            continue;
        }
        double ta = (l - o[a]) * inv[a], tb = (h - o[a]) * inv[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

// Orthonormal basis around a unit vector (Duff et al. 2017, branchless).
struct Frame {
    Vec3 s, t, n;
    Frame() = default;
    explicit Frame(const Vec3 &normal) : n(normal) {
        double sign = std::copysign(1.0, n.z);
        double a = -1.0 / (sign + n.z);
        double b = n.x * n.y * a;
        s = {1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x};
        t = {b, sign + n.y * n.y * a, -n.y};
    }
    Vec3 to_world(const Vec3 &v) const { return s * v.x + t * v.y + n * v.z; }
    Vec3 to_local(const Vec3 &v) const { return {dot(v, s), dot(v, t), dot(v, n)}; }
};

// An "unlimited" path ends after this many real scattering events: depths are recorded in 16
// bits, and only a closed, perfectly white scene (where no path ever loses throughput, so the
// throughput roulette never ends one) comes near it.
constexpr int kMaxPathEvents = 32767;

// Mitsuba's max_depth, the one rule every method applies: a path may have fewer than
// max_depth real scattering events (null crossings and null collisions are free). So 0 renders
// black, 1 shows emitters seen directly, 2 adds direct light, and a negative value (-1) is
// unlimited (up to kMaxPathEvents). Each method counts the events of the path it builds and
// asks allows(count).
// A lower bound too, for the gathering kernels' min_depth (vpl.h; 1, no bound, elsewhere): a
// path of k events counts iff also k + 1 >= min_depth (Mitsuba's count of vertices), so the
// images at min_depth m and at max_depth m - 1 add up to the whole image. allows() still
// decides whether a path may go on; counts() whether what it adds reaches the image.
class DepthLimit {
public:
    explicit DepthLimit(int max_depth) : max_depth_(max_depth) {}
    bool allows(int events) const { return max_depth_ < 0 ? events < kMaxPathEvents : events < max_depth_; }
    bool counts(int events) const { return events + 1 >= min_depth_ && allows(events); }
    bool unlimited() const { return max_depth_ < 0; }
    int max_depth() const { return max_depth_; }
    void set_min_depth(int min_depth) { min_depth_ = min_depth; }
    int min_depth() const { return min_depth_; }

private:
    int max_depth_;
    int min_depth_ = 1;
};

// Power heuristic with beta = 2 (Veach 1997, eq. 9.13) for two strategies.
// A NaN or negative pdf gives a NaN weight, so the sample is counted as non-finite instead
// of vanishing.
inline double power_heuristic(double pdf_a, double pdf_b) {
    if (!(pdf_a >= 0 && pdf_b >= 0)) return std::numeric_limits<double>::quiet_NaN();
    double a = pdf_a * pdf_a, b = pdf_b * pdf_b;
    if (a + b >= std::numeric_limits<double>::min() && a + b < kInf) return a / (a + b);
    if (pdf_a == 0) return 0.0;
    // Squares beyond double's range (pdfs below ~1e-154 or above ~1e154, or infinite) would
    // give 0 / 0 or inf / inf: the pdfs' ratio gives the weight (NaN for two infinite ones).
    double r = pdf_b / pdf_a;
    return 1 / (1 + r * r);
}

}  // namespace pgi
