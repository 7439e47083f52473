// The binding of a gathering kernel's pilot (pilot.h), shared by pm's and ppb's bindings.
#pragma once

#include "bindings.h"
#include "pilot.h"

namespace pgi::bind {

// set_pilot(surface_neighbours, <medium_neighbours>, extent_fraction, path_stride), pilot and
// pilot_result on a kernel that has them; `medium_neighbours` names its second argument.
template <typename K>
nb::class_<K> &bind_pilot(nb::class_<K> &cls, const char *medium_neighbours) {
    return cls
        .def("set_pilot", &K::set_pilot, "surface_neighbours"_a, nb::arg(medium_neighbours), "extent_fraction"_a,
             "path_stride"_a)
        .def_prop_ro("pilot", &K::pilot)
        // (distances, extent, free paths) of a pilot pass: kernel -1 the surfaces', m medium m's.
        .def(
            "pilot_result",
            [](const K &k, int kernel) {
                const PilotResult &r = k.pilot_result(kernel);
                std::vector<double> d = r.distances;
                size_t n = d.size();
                std::vector<double> f = r.free_paths;
                size_t nf = f.size();
                return nb::make_tuple(to_numpy(std::move(d), {n}), r.extent, to_numpy(std::move(f), {nf}));
            },
            "kernel"_a);
}

}  // namespace pgi::bind
