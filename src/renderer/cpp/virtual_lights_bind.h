// What the bindings of the virtual-light kernels share (vpl_bind.cpp, vsl_bind.cpp,
// vrl_bind.cpp): records made from probe arguments, the counts every gathering kernel reports,
// and the clamp of the kernels whose point lights transfer as vpl's.
#pragma once

#include "bindings.h"
#include "vpl.h"

namespace pgi::bind {

// A gather point from probe arguments: on triangle `triangle` (>= 0), or in medium `medium`.
inline GatherPoint probe_gather_point(const Scene &s, V3 pos, V3 wo, int triangle, int medium) {
    if (triangle >= int(s.triangles.size()) || medium >= int(s.media.size()) || (triangle < 0 && medium < 0))
        throw std::invalid_argument("gather point: a triangle or a medium of the scene expected");
    return GatherPoint{vec(pos), normalize(vec(wo)), triangle, medium};
}

// A virtual light of power 1 from probe arguments (axis: wi, a normal or a direction).
inline VirtualLight probe_virtual_light(const Scene &s, VirtualLightKind kind, V3 pos, V3 axis, int triangle,
                                        int medium, int light) {
    const bool on_surface = kind == VirtualLightKind::Surface || kind == VirtualLightKind::AreaLight;
    if ((on_surface && (triangle < 0 || triangle >= int(s.triangles.size()))) ||
        (kind == VirtualLightKind::Medium && (medium < 0 || medium >= int(s.media.size()))) ||
        (kind == VirtualLightKind::Spot && (light < 0 || light >= int(s.lights.size()))))
        throw std::invalid_argument("virtual light: its triangle, medium or light is not the scene's");
    VirtualLight v;
    v.kind = kind;
    v.pos = vec(pos);
    v.axis = normalize(vec(axis));
    v.power = RGB(1.0);
    v.triangle = triangle;
    v.medium = medium;
    v.light = light;
    return v;
}

// The kernel's constructor and counts, as vpl's and vsl's bindings give them.
template <typename K>
nb::class_<K> &bind_gathering(nb::class_<K> &cls) {
    return cls
        .def(nb::init<std::shared_ptr<const Scene>, std::shared_ptr<const LightPaths>, int, int, uint64_t, int, int>(),
             "scene"_a, "light_paths"_a, "max_depth"_a, "rr_depth"_a, "seed"_a, "spp_per_iteration"_a, "threads"_a)
        .def("set_free_flight_fraction", &K::set_free_flight_fraction, "fraction"_a,
             "The probability of drawing a camera segment's point for a light by its free-flight "
             "density rather than equi-angularly about the light.")
        .def("set_share_lights", &K::set_share_lights, "on"_a,
             "Each of a pixel's samples gathers its share of the lights (the exact ones: all).")
        .def("set_chunk_pairs", &K::set_chunk_pairs, "pairs"_a,
             "Job x light pairs per chunk of shadow rays (speed and memory only; not the image).")
        .def_prop_ro("continuations", &K::continuations,
                     "Camera paths go on past their gather points (the scene has specular surfaces).")
        .def_prop_ro("virtual_lights", [](const K &k) { return k.stats().lights; })
        .def_prop_ro("gather_jobs", [](const K &k) { return k.stats().jobs; })
        .def_prop_ro("pairs", [](const K &k) { return k.stats().pairs; })
        .def_prop_ro("shadow_rays_aimed", &K::shadow_rays_aimed);
}

// The clamp of a kernel whose point lights transfer as vpl's (PointTransfer, vpl.h).
template <typename K>
nb::class_<K> &bind_clamp(nb::class_<K> &cls) {
    return cls
        .def("set_clamp", [](K &k, PointTransfer::Clamp mode, double distance, double alpha) {
                 k.transfer().set_clamp(mode, distance, alpha);
             }, "mode"_a, "distance"_a, "alpha"_a,
             "none; fixed at `distance` (world units); or progressive from it, d_i = d_1 i^(alpha - 1).")
        .def("clamp_distance", [](const K &k, int64_t iteration) { return k.transfer().distance(iteration); },
             "iteration"_a, "The clamp's d_i in world units (0: none) of iteration `iteration` (0-based).");
}

}  // namespace pgi::bind
