// Photon beams and the acceleration structure that finds, for a query ray,
// every beam whose cylinder of radius r the ray passes through.
//   Jarosz, Nowrouzezahrai, Sadeghi & Jensen 2011, "A comprehensive theory of
//   volumetric radiance estimation using photon points and beams" (beam x beam
//   estimators, the "BB1D" 1D blur, its 1/sin(theta) Jacobian);
//   Jarosz, Nowrouzezahrai, Thomas, Sloan & Zwicker 2011, "Progressive photon beams".
//
// A beam is a segment (origin, unit dir, length) carrying a flux weight; its
// cylinder is every point within r of the segment. The BB1D estimator needs,
// for a query ray, the closest approach of the two lines: the parameters
// t_beam on the beam and t_ray on the ray, the distance between the lines, and
// sin(theta) of the angle between them. A pair counts iff the distance is
// below r and both closest points lie on their segments.
//
// Long beams have boxes that overlap everything, so each beam is bounded by
// pieces of at most `max_piece_length`; the BVH (median split on the widest
// centroid axis, up to 4 pieces per leaf) is built over the pieces' boxes grown
// by r. A pair is reported by the one piece whose parameter range holds
// t_beam, so no beam is counted twice. Memory is bounded: at most `max_beams`
// beams (more are dropped, in order, and counted) and `kPiecesPerBeam` pieces
// per stored beam on average (pieces grow longer to stay within it): about
// 112 + 16 * 72 + 16 * 32 / 2 bytes per beam at most (a Beam is 112 bytes), and the
// build's temporary arrays about as much again at their peak.
// Visits follow the tree order, so sums over a query are deterministic.
// Each medium's beams may have a radius of their own (the default radii differ by medium:
// methods/radii.py). Built with radius 0, the tree also finds the distance within which the k
// nearest beams of a ray lie (kth_nearest, for the pilot that derives those radii).
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "common.h"
#include "k_nearest.h"

namespace pgi {

struct Beam {
    Vec3 origin, dir;  // dir unit
    double length = 0;
    RGB power{0.0};    // flux weight at the origin (see subpaths.h)
    RGB spectral_ratio{1.0};  // the light path's channel pdf ratios at the origin
    int32_t medium = -1;
    int16_t depth = 0; // real scattering events of the light path before the origin (16 bits
                       // suffice: see MediumSegment)
};

// Closest approach of a query ray and a beam's axis.
struct BeamHit {
    double t_beam = 0;     // along the beam from its origin
    double t_ray = 0;      // along the query ray from its origin
    double distance = 0;   // between the two lines, < r
    double sin_theta = 0;  // of the angle between beam and ray, > kMinBeamSine
};

// Nearly parallel pairs are skipped: the 1/sin(theta) weight has a logarithmically
// infinite variance there, and the skipped solid angle (~1e-8 of the sphere) is negligible.
constexpr double kMinBeamSine = 1e-4;
constexpr int kPiecesPerBeam = 16;

class BeamBvh {
public:
    // A part of a beam: the tree bounds beams piece by piece.
    struct Piece {
        Vec3 origin, dir;  // the beam's, copied: leaf tests read pieces sequentially
        double t0, t1;     // parameter range on the beam; the last piece's t1 is the length
        bool last;         // t1 is the beam's end (closed range)
        int32_t beam;
        // Whether the beam's point at parameter t belongs to this piece (each to one piece).
        bool holds(double t) const { return t >= t0 && (t < t1 || (last && t == t1)); }
    };

    explicit BeamBvh(size_t max_beams = size_t(1) << 22) : max_beams_(max_beams) {}

    // Replaces the stored beams; beams of zero length or power are skipped. Beams of medium m
    // have the radius radii[m] (one value: every beam's).
    void build(std::vector<Beam> beams, std::vector<double> radii, double max_piece_length);
    void build(std::vector<Beam> beams, double radius, double max_piece_length) {
        build(std::move(beams), std::vector<double>{radius}, max_piece_length);
    }

    // visit(beam_index, BeamHit) for every beam whose cylinder the ray (o, unit d)
    // crosses at its closest approach with t_ray in [0, tmax].
    template <typename Visit>
    void query(const Vec3 &o, const Vec3 &d, double tmax, Visit &&visit) const;

    // visit(piece) for every piece that a point of the ray (o, unit d), t in [0, tmax], may lie
    // within its beam's radius of: estimators with kernels of their own (ppb's near a medium's
    // boundary) test the pieces themselves, and take a pair from the piece that holds its point
    // on the beam (Piece::holds).
    template <typename Visit>
    void query_pieces(const Vec3 &o, const Vec3 &d, double tmax, Visit &&visit) const;

    // The distance within which lie the k nearest beams that accept(beam_index) takes, by the
    // estimator's own measure (the distance between the lines, both closest points on their
    // segments, the ray's within [0, tmax]), searching no farther than max_radius: kInf if
    // fewer than k lie within it. Needs a tree built with radius 0.
    template <typename Accept>
    double kth_nearest(const Vec3 &o, const Vec3 &d, double tmax, size_t k, double max_radius, Accept &&accept) const;

    const std::vector<Beam> &beams() const { return beams_; }
    // The radius of the beams of a medium.
    double radius(int32_t medium) const {
        if (radii_.size() == 1) return radii_[0];
        return medium >= 0 && size_t(medium) < radii_.size() ? radii_[size_t(medium)] : 0.0;
    }
    size_t piece_count() const { return pieces_.size(); }
    size_t node_count() const { return nodes_.size(); }
    double piece_length() const { return piece_length_; }
    size_t max_beams() const { return max_beams_; }
    uint64_t truncated() const { return truncated_; }  // beams dropped by the bound, all builds
    uint64_t escaped() const { return escaped_; }      // infinite beams dropped, all builds

private:
    // The pieces of the leaves whose boxes, grown by grow() (asked at each node), the ray
    // (o, unit d), t in [0, tmax], meets: visit(piece), the left child first (a fixed order).
    template <typename Grow, typename Visit>
    void walk_pieces(const Vec3 &o, const Vec3 &d, double tmax, Grow &&grow, Visit &&visit) const;

    struct Node {
        float lo[3], hi[3];  // box of the pieces below, grown by the radius, rounded outwards
        int32_t first;   // leaf: first piece; inner: the left child (the right one is first + 1)
        int32_t count;   // leaf: number of pieces; inner: 0
    };
    static constexpr int kLeafSize = 4;
    static constexpr int kMaxStack = 96;

    std::vector<Beam> beams_;
    std::vector<Piece> pieces_;
    std::vector<Node> nodes_;
    std::vector<double> radii_{0.0};  // by medium, or one for every beam
    double piece_length_ = 0;
    size_t max_beams_;
    uint64_t truncated_ = 0;
    uint64_t escaped_ = 0;
};

// Closest approach of the lines (o_b + s u) and (o_r + t v), u and v unit.
// Returns false for (nearly) parallel lines.
inline bool closest_approach(const Vec3 &o_b, const Vec3 &u, const Vec3 &o_r, const Vec3 &v, BeamHit &h) {
    Vec3 n = cross(u, v);
    double sin2 = dot(n, n);
    if (sin2 < kMinBeamSine * kMinBeamSine) return false;
    Vec3 w = o_r - o_b;
    // Solve o_b + s u + (distance) n/|n| = o_r + t v for s and t (Cramer's rule).
    h.t_beam = dot(cross(w, v), n) / sin2;
    h.t_ray = dot(cross(w, u), n) / sin2;
    h.sin_theta = std::sqrt(sin2);
    h.distance = std::abs(dot(w, n)) / h.sin_theta;
    return true;
}

template <typename Grow, typename Visit>
void BeamBvh::walk_pieces(const Vec3 &o, const Vec3 &d, double tmax, Grow &&grow, Visit &&visit) const {
    if (nodes_.empty()) return;
    const Vec3 inv(1 / d.x, 1 / d.y, 1 / d.z);
    int stack[kMaxStack];
    int top = 0;
    stack[top++] = 0;
    while (top) {
        const Node &n = nodes_[stack[--top]];
        if (!ray_meets_box(o, d, inv, n.lo, n.hi, tmax, grow())) continue;
        if (n.count == 0) {
            // Children are pushed so that the left one is visited first: a fixed order.
            stack[top++] = n.first + 1;
            stack[top++] = n.first;
            continue;
        }
        for (int32_t i = n.first; i < n.first + n.count; ++i) visit(pieces_[i]);
    }
}

template <typename Visit>
void BeamBvh::query_pieces(const Vec3 &o, const Vec3 &d, double tmax, Visit &&visit) const {
    walk_pieces(o, d, tmax, [] { return 0.0; }, visit);
}

template <typename Visit>
void BeamBvh::query(const Vec3 &o, const Vec3 &d, double tmax, Visit &&visit) const {
    const bool one_radius = radii_.size() == 1;
    query_pieces(o, d, tmax, [&](const Piece &p) {
        BeamHit h;
        if (!closest_approach(p.origin, p.dir, o, d, h)) return;
        const double r = one_radius ? radii_[0] : radius(beams_[size_t(p.beam)].medium);
        if (!(h.distance < r) || h.t_ray < 0 || h.t_ray > tmax) return;
        // The pair belongs to the piece holding t_beam.
        if (!p.holds(h.t_beam)) return;
        visit(p.beam, h);
    });
}

template <typename Accept>
double BeamBvh::kth_nearest(const Vec3 &o, const Vec3 &d, double tmax, size_t k, double max_radius,
                            Accept &&accept) const {
    if (nodes_.empty() || k == 0) return kInf;
    KSmallest kth(k, max_radius);
    // Boxes of a tree of radius 0, grown by the distance still sought.
    walk_pieces(o, d, tmax, [&] { return kth.bound(); }, [&](const Piece &p) {
        BeamHit h;
        if (!closest_approach(p.origin, p.dir, o, d, h)) return;
        if (!(h.distance < kth.bound()) || h.t_ray < 0 || h.t_ray > tmax || !p.holds(h.t_beam)) return;
        if (accept(p.beam)) kth.add(h.distance);
    });
    return kth.kth();
}

}  // namespace pgi
