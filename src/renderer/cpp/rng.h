// Counter-based random numbers: a value depends only on (key, dimension), so an
// image is the same whatever the thread count or the order paths are processed in.
#pragma once

#include <cstdint>

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
    Sampler fork() { return split(0x466f726b00000000ull + uint64_t(++dim)); }
};

}  // namespace pgi
