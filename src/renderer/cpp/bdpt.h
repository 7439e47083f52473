// bdpt: bidirectional path tracing in participating media, with every connection strategy and
// multiple importance sampling.
//   Lafortune & Willems 1993, "Bi-directional path tracing"; 1996, "Rendering participating
//     media with bidirectional path tracing";
//   Veach & Guibas 1994/1995; Veach 1997, "Robust Monte Carlo methods for light transport
//     simulation", ch. 10 (the strategies, the MIS weights as a running product of density
//     ratios);
//   Pharr, Jakob & Humphreys, "Physically Based Rendering", 3rd ed., ch. 16.3 (the same walk);
//   the media formulation (free-flight probabilities in the densities) as in Mitsuba 0.6's and
//   SmallUPBP's volumetric bidirectional path tracers.
//
// One iteration, as passes (passes.h; methods/bdpt.py runs them in this order):
//   1. LightPaths (subpaths.h), complete: N light subpaths y_0 (on a light) y_1 ... y_{S-1};
//   2. CameraPaths, complete: N camera subpaths z_0 (the camera) z_1 ... z_{T-1}, N = spp x
//      pixels; camera sample k pairs with light subpath k;
//   3. this kernel: begin enumerates, for every sample, every strategy (s, t) that can join a
//      prefix of s light vertices to a prefix of t camera vertices, computes its unweighted
//      contribution and its MIS weight from the recorded densities, and queues a shadow ray
//      for each that needs one; the shadow passes trace them through null boundaries and
//      media (transmittance by the scene's estimator); end adds every weighted contribution to
//      the film, in a fixed order.
//
// The strategies and their contributions (beta: a vertex's recorded throughput, which holds
// sigma_s and the flight weights of its subpath; f: the BSDF times |cos| at the vertex towards
// the other end, or the phase function; T: transmittance of the connection):
//   s = 0, t >= 2   z_{t-1} lies on an emitter:   C = beta(z_{t-1}) L_e(z_{t-1} -> z_{t-2})
//   s = 1, t >= 2   a fresh light sample y from z_{t-1} (pt's next-event estimation):
//                   C = beta(z_{t-1}) f(z_{t-1}) L_e(y) T / p_light(y)  (solid angle at z_{t-1})
//   s >= 2, t >= 2  C = beta(y_{s-1}) f(y_{s-1}) f(z_{t-1}) beta(z_{t-1}) T / |y_{s-1} - z_{t-1}|^2
//   s >= 1, t = 1   y_{s-1} joined to the camera and splatted to the pixel it projects to (lt.h):
//                   C = beta(y_{s-1}) f(y_{s-1}) W_e(z_0 -> y_{s-1}) T / pixels
// with W_e the pinhole's importance over |y - z_0|^2 (lt.h's connect_to_camera; dividing by the
// pixels instead of by the N light paths makes the splats of an iteration an estimate of spp
// samples per pixel, as the camera strategies' are). A path of s + t vertices has s + t - 2
// real scattering events, within max_depth (Mitsuba's meaning) for every strategy alike.
//
// MIS: the power heuristic (beta = 2) over the strategies s' + t' = s + t of the same path,
//   w(s, t) = 1 / (1 + sum over s' != s of (p_{s'} / p_s)^2),
// the ratios a running product outwards from the connection (Veach 1997, sec. 10.2;
// pbrt-v3's MISWeight): moving the connection one vertex x towards the camera multiplies the
// ratio by p_rev(x) / p_fwd(x), one towards the lights by the same of the light vertex, each
// density remapped to 1 where it is 0 and a strategy skipped where either of its connection's
// vertices scattered by a delta BSDF (or is a delta light: then no path reaches it). The
// densities are those of path_records.h and densities.h, including the free-flight
// probabilities from deterministic stand-ins, so the weights of one path sum to one also in
// density grids; those the connection changes (the reverse densities of its two ends and of
// their neighbours) are computed here. Every other strategy samples the connection's edge, so
// each ratio holds its flight probability exp(-tau) once: the weight is computed with it left
// out and completed as 1 / (1 + exp(-2 tau) rest) once the shadow ray has measured tau.
//
// Connections (s >= 2 and t >= 2) are made only while s and t are at most `max_connect`
// (default 16: each costs a shadow ray, and their count grows as S x T); the MIS sums leave
// out the strategies that are not made, so the weights still sum to one. In white, dense media
// (hundreds of events per path) this keeps the work linear in the subpaths' length.
#pragma once

#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include "passes.h"
#include "subpaths.h"

namespace pgi {

// Whether strategy (s, t) is made when connections stop at max_connect (see above).
inline bool bdpt_made(int max_connect, int s, int t) { return s < 2 || t < 2 || (s <= max_connect && t <= max_connect); }

// The MIS sum of strategy (s, t) (see above), with the flight of its connection's edge left
// out: `light` and `camera` are the two prefixes, in the order each subpath sampled them, with
// their recorded densities (pdf_fwd from their own side, pdf_rev from the other); the densities
// the connection changes are computed here. `fresh_light`: the light vertex of s = 1 when a
// fresh light sample, not the light subpath's, is joined.
double bdpt_mis_rest(const Scene &scene, int max_connect, const PathVertex *const *light, int s,
                     const PathVertex *const *camera, int t, const PathVertex *fresh_light);

// The weights of every strategy of one whole path (a probe for tests: they sum to one). The
// path's vertices come from the light end (its light's vertex first, the camera's last) with
// the stand-in optical depth of each of its edges; its densities are computed from the
// positions alone, in both directions. Entries: (s, t, weight), for every split that can
// sample the path.
std::vector<std::tuple<int, int, double>> bdpt_path_weights(const Scene &scene, int max_connect,
                                                            const std::vector<PathVertex> &path,
                                                            const std::vector<double> &edge_tau);

class BidirectionalPathTracing : public SingleLane<BidirectionalPathTracing>, public NoExtensionRays {
public:
    BidirectionalPathTracing(std::shared_ptr<const Scene> scene, std::shared_ptr<const LightPaths> light_paths,
                             std::shared_ptr<const CameraPaths> camera_paths, int max_depth, uint64_t seed,
                             int spp_per_iteration, int threads, int max_connect);

    // Pass 1: every strategy of every sample of this iteration's subpaths (traced first).
    void begin(int64_t iteration);
    size_t shadow_slots() const { return shadow_.opened(); }
    size_t shadow_rays(const RayBuffers &out) { return shadow_.compact_and_write(out, threads_); }
    void resolve_shadows(const Hits &hits);
    // Last pass: the weighted contributions to the film, in sample and strategy order.
    void end();

    // Per path length and strategy, the weighted and the unweighted contributions, as images
    // (a pbrt-style view of which strategy carries which light); off by default.
    void set_strategy_images(bool on) { strategy_images_ = on; }
    struct StrategyImages {
        Film weighted, unweighted;
    };
    const std::map<std::pair<int, int>, StrategyImages> &strategy_images() const { return strategies_; }

    const Film &film() const { return film_; }
    const Scene &scene() const { return *scene_; }
    uint64_t density_lookups() const { return stats_.density_lookups; }
    uint64_t connections() const { return connections_made_; }


    // One strategy of one sample: its contribution before the connection's transmittance and
    // weight, and what completes the weight (see above).
    struct Connection {
        RGB value{0.0};          // unweighted; times T once the shadow ray arrives
        double mis_rest = 0;     // sum of squared density ratios, the connection's flight out
        double tau = 0;          // the connection's stand-in optical depth (shadow ray)
        int64_t pixel = -1;
        int16_t s = 0, t = 0;
        bool needs_ray = false;  // s = 0 needs none: its value is final
        bool arrived = false;
    };

private:
    struct Subpath {
        const PathVertex *const *vertices;  // in depth order
        int count;
    };
    Subpath light_subpath(int64_t k) const;
    Subpath camera_subpath(int64_t k) const;
    // Counts (fill = false) or fills the connections of sample k from slot `first`.
    int connect_sample(int64_t k, int64_t first, bool fill, Sampler rng);
    double mis_rest(const PathVertex *const *light, int s, const PathVertex *const *camera, int t,
                    const PathVertex *fresh_light) const {
        return bdpt_mis_rest(*scene_, max_connect_, light, s, camera, t, fresh_light);
    }
    bool made(int s, int t) const { return bdpt_made(max_connect_, s, t); }

    std::shared_ptr<const Scene> scene_;
    std::shared_ptr<const LightPaths> light_paths_;
    std::shared_ptr<const CameraPaths> camera_paths_;
    DepthLimit depth_;
    uint64_t seed_;
    int spp_, threads_, max_connect_;
    int64_t iteration_ = 0;
    // Each sample's vertices, in depth order: index ranges into the subpaths' records.
    std::vector<const PathVertex *> light_order_, camera_order_;
    std::vector<int64_t> light_first_, camera_first_;
    std::vector<int64_t> first_connection_;  // per sample, then the total
    std::vector<Connection> connections_;
    std::vector<PathVertex> fresh_lights_;  // s = 1: the light vertex each connection sampled
    ShadowQueue shadow_;
    Film film_;
    bool strategy_images_ = false;
    std::map<std::pair<int, int>, StrategyImages> strategies_;
    MediumStats stats_;
    uint64_t connections_made_ = 0;
};

}  // namespace pgi
