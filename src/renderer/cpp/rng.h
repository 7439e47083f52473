// Counter-based random numbers: a value depends only on (key, dimension), so an
// image is the same whatever the thread count or the order paths are processed in.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iterator>

namespace pgi {

inline uint64_t mix64(uint64_t z) {  // SplitMix64 finaliser
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

// Key of one independent stream, e.g. (seed, sample index, pixel).
inline uint64_t stream_key(uint64_t a, uint64_t b, uint64_t c) {
    return mix64(mix64(mix64(a) ^ b) ^ (c * 0xd1342543de82ef95ull));
}

// Tags that keep a render's streams apart: a family of paths keys its streams by seed ^ its
// tag, and a child stream split off for one purpose takes that purpose's tag. Most spell
// their name in ASCII; ppb's value predates the names (images stay as they were).
namespace stream_tag {
constexpr uint64_t kLightPaths = 0x4c69676874506174ull;    // "LightPat": lt, pm, sppm, ppb
constexpr uint64_t kConnections = 0x436f6e6e65637473ull;   // "Connects": lt's camera connections
constexpr uint64_t kGatherPaths = 0x4761746865725061ull;   // "GatherPa": pm's and sppm's camera paths
constexpr uint64_t kCameraPaths = 0x43616d6572615061ull;   // "CameraPa": camera subpaths (bdpt)
constexpr uint64_t kBdptConnections = 0x42647074436f6e6eull;  // "BdptConn": bdpt's connections
constexpr uint64_t kBeamGatherPaths = 0x5bd1e995b5ull;     // ppb's camera paths
constexpr uint64_t kVirtualLightGather = 0x564c476174686572ull;  // "VLGather": vpl's, vsl's camera paths
constexpr uint64_t kHero = 0x4865726f00000000ull;          // "Hero": a path's hero channel
constexpr uint64_t kFork = 0x466f726b00000000ull;          // "Fork" + n: Sampler::fork's children
constexpr uint64_t kAll[] = {kLightPaths,      kConnections,     kGatherPaths,        kCameraPaths,
                             kBdptConnections, kBeamGatherPaths, kVirtualLightGather, kHero,
                             kFork};
constexpr bool all_distinct() {
    for (size_t i = 0; i < std::size(kAll); ++i)
        for (size_t j = i + 1; j < std::size(kAll); ++j)
            if (kAll[i] == kAll[j]) return false;
    return true;
}
static_assert(all_distinct(), "two stream families share a tag");
}  // namespace stream_tag

struct Sampler {
    uint64_t key = 0;
    uint32_t dim = 0;
    Sampler() = default;
    explicit Sampler(uint64_t k) : key(k) {}
    // Uniform in [0, 1) with 53 random bits: SplitMix64 stepped to `dim`,
    // from a starting point (the key) that is itself a hash.
    double next() {
        uint64_t h = mix64(key + 0x632be59bd9b4e019ull * uint64_t(++dim));
        return double(h >> 11) * 0x1.0p-53;
    }
    // A child stream, e.g. for a shadow ray, independent of this one. The same tag
    // gives the same child: tag by something that differs between uses.
    Sampler split(uint64_t tag) const { return Sampler(mix64(key ^ mix64(tag + 0x8cb92ba72f3d8dd7ull))); }
    // A new child stream at each call: it uses up one dimension of this stream.
    Sampler fork() { return split(stream_tag::kFork + uint64_t(++dim)); }
};

}  // namespace pgi
