// Helpers shared by the binding files: array conversion, ray/hit buffers, results handed
// back to numpy, the one helper that binds every kernel's passes (bind_kernel). Each method
// binds itself in a file of its own, registered with PGI_BINDING.
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/tuple.h>

#include <array>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "passes.h"

namespace pgi::bind {

namespace nb = nanobind;
using namespace nb::literals;

using V3 = std::array<double, 3>;
template <typename T>
using Array = nb::ndarray<T, nb::c_contig, nb::device::cpu>;
template <typename T>
using NumpyOut = nb::ndarray<nb::numpy, T>;

inline Vec3 vec(const V3 &a) { return {a[0], a[1], a[2]}; }

// Whether this is the interpreter's main thread, the one that runs Python's signal handlers
// (asked of `threading` each time: after a fork the main thread may be another).
inline bool on_main_thread() {
    nb::object main = nb::module_::import_("threading").attr("main_thread")();
    return nb::cast<unsigned long>(main.attr("ident")) == PyThread_get_thread_ident();
}

// After a pass: if Ctrl-C or SIGTERM arrived meanwhile (interrupt_flag), the pass may have
// been cut short. On the main thread the flag is cleared and Python's handler raises its
// exception now (KeyboardInterrupt, or the CLI's Terminated); if it does not, a
// KeyboardInterrupt is raised all the same. Another thread (one of pt's lanes) cannot run
// the handler: it raises KeyboardInterrupt and leaves the flag set, so that the other lanes
// stop at their next pass too and the main thread still sees the signal.
inline void raise_if_interrupted() {
    if (!interrupt_flag().load()) return;
    if (!on_main_thread()) {
        PyErr_SetNone(PyExc_KeyboardInterrupt);
        throw nb::python_error();
    }
    if (!interrupt_flag().exchange(false)) return;
    if (PyErr_CheckSignals() == 0) PyErr_SetNone(PyExc_KeyboardInterrupt);
    throw nb::python_error();
}

// Runs a pass with the GIL released (other Python threads, and Embree calls in them, go on),
// then raise_if_interrupted.
template <typename F>
decltype(auto) released(F &&pass) {
    using Result = std::invoke_result_t<F>;
    if constexpr (std::is_void_v<Result>) {
        {
            nb::gil_scoped_release release;
            pass();
        }
        raise_if_interrupted();
    } else {
        Result out = [&]() -> Result {
            nb::gil_scoped_release release;
            return pass();
        }();
        raise_if_interrupted();
        return out;
    }
}

inline void check_len(size_t got, size_t want, const char *what) {
    if (got < want) throw std::invalid_argument(std::string(what) + ": buffer too small");
}

inline RayBuffers ray_buffers(Array<float> org, Array<float> dir, Array<float> tmax) {
    if (org.ndim() != 2 || org.shape(1) != 3 || dir.ndim() != 2 || dir.shape(1) != 3 || tmax.ndim() != 1)
        throw std::invalid_argument("ray buffers must be (n, 3), (n, 3), (n,) float32");
    size_t n = tmax.shape(0);
    check_len(org.shape(0), n, "origins");
    check_len(dir.shape(0), n, "directions");
    return RayBuffers{org.data(), dir.data(), tmax.data(), n};
}

inline Hits hits_of(Array<float> tfar, Array<int32_t> prim, Array<float> u, Array<float> v) {
    size_t n = prim.shape(0);
    check_len(tfar.shape(0), n, "tfar");
    check_len(u.shape(0), n, "u");
    check_len(v.shape(0), n, "v");
    return Hits{tfar.data(), u.data(), v.data(), prim.data(), n};
}

template <typename T>
inline NumpyOut<T> to_numpy(std::vector<T> &&data, std::initializer_list<size_t> shape) {
    auto heap = std::make_unique<std::vector<T>>(std::move(data));
    T *ptr = heap->data();
    // The capsule owns the vector from here on and frees it with the array.
    nb::capsule owner(heap.get(), [](void *p) noexcept {
        std::unique_ptr<std::vector<T>>(static_cast<std::vector<T> *>(p));
    });
    heap.release();
    return NumpyOut<T>(ptr, shape.size(), shape.begin(), owner);
}

inline NumpyOut<double> film_image(const Film &f) {
    std::vector<double> img(f.sum.size());
    double inv = f.samples_per_pixel ? 1.0 / double(f.samples_per_pixel) : 0.0;
    for (size_t i = 0; i < img.size(); ++i) img[i] = f.sum[i] * inv;
    return to_numpy(std::move(img), {size_t(f.height), size_t(f.width), 3});
}


// The lane passes of the iteration protocol (passes.h): next_rays / shade, and the shadow-ray
// passes, resolved from Embree's closest hits (tfar, primitive id) or, when no surface of the
// scene is a null boundary (`shadows_any_hit`), from the cheaper occlusion query (`blocked`
// >= 0 where something blocks).
template <typename Lane>
void bind_lane_passes(nb::class_<Lane> &cls) {
    cls.def("next_rays",
            [](Lane &l, Array<float> o, Array<float> d, Array<float> t) {
                RayBuffers b = ray_buffers(o, d, t);
                return released([&] { return l.next_rays(b); });
            }, "o"_a.noconvert(), "d"_a.noconvert(), "t"_a.noconvert(),
            "Writes the rays of the paths in flight (the first call of an iteration: their first "
            "rays) into origins, directions and tmax; returns their count (0: the lane is done).")
        .def("shade",
             [](Lane &l, Array<float> tfar, Array<int32_t> prim, Array<float> u, Array<float> v) {
                 Hits h = hits_of(tfar, prim, u, v);
                 return released([&] { return l.shade(h); });
             }, "tfar"_a, "prim"_a, "u"_a, "v"_a,
             "What each ray of the last next_rays found (Embree's closest hits: distance, "
             "primitive or -1, barycentrics); returns the number of shadow rays it queued.")
        .def("shadow_rays",
             [](Lane &l, Array<float> o, Array<float> d, Array<float> t) {
                 RayBuffers b = ray_buffers(o, d, t);
                 return released([&] { return l.shadow_rays(b); });
             }, "o"_a.noconvert(), "d"_a.noconvert(), "t"_a.noconvert(),
             "Writes the next segment of every shadow ray still travelling; returns their count.")
        .def("resolve_shadows",
             [](Lane &l, Array<float> tfar, Array<int32_t> prim) {
                 check_len(tfar.shape(0), prim.shape(0), "tfar");
                 Hits h{tfar.data(), nullptr, nullptr, prim.data(), prim.shape(0)};
                 released([&] { l.resolve_shadows(h); });
             }, "tfar"_a, "prim"_a,
             "Advances the shadow rays of the last shadow_rays by their closest hits: blocked, "
             "arrived (its value delivered) or through a null boundary (another segment).")
        .def("resolve_occlusion",
             [](Lane &l, Array<int32_t> blocked) {
                 Hits h{nullptr, nullptr, nullptr, blocked.data(), blocked.shape(0), true};
                 released([&] { l.resolve_shadows(h); });
             }, "blocked"_a,
             "As resolve_shadows, from an occlusion query (blocked >= 0 where something blocks); "
             "only where the scene has no null boundary (shadows_any_hit).")
        .def_prop_ro("capacity", [](const Lane &l) { return l.capacity(); })
        .def_prop_ro("shadow_slots", [](const Lane &l) { return l.shadow_slots(); })
        .def_prop_ro("shadows_any_hit", [](const Lane &l) { return !l.scene().has_null_surfaces; });
}

template <typename Kernel, typename = void>
struct has_film : std::false_type {};
template <typename Kernel>
struct has_film<Kernel, std::void_t<decltype(std::declval<const Kernel &>().film())>> : std::true_type {};

// Binds a kernel under `name` with the iteration protocol (passes.h): begin / end, its lanes
// (a kernel of one lane is its own lane; another's lanes are bound as `lane_name`), their
// passes, its density lookups and, if it has a film, the image. The caller adds the
// constructor and what is the kernel's own.
template <typename Kernel>
nb::class_<Kernel> bind_kernel(nb::module_ &m, const char *name, const char *lane_name = nullptr) {
    using Lane = typename Kernel::Lane;
    nb::class_<Kernel> cls(m, name);
    if constexpr (std::is_same_v<Lane, Kernel>) {
        bind_lane_passes(cls);
    } else {
        nb::class_<Lane> lane(m, lane_name);
        bind_lane_passes(lane);
    }
    cls.def("begin", [](Kernel &k, int64_t iteration) { released([&] { k.begin(iteration); }); }, "iteration"_a,
            "Starts iteration `iteration`: its paths, and whatever it builds from the kernels run "
            "before it (photon maps, beams, connections); writes no ray.")
        .def("end", [](Kernel &k) { released([&] { k.end(); }); },
             "Ends the iteration: its results to the film (or records), in a fixed order.")
        .def_prop_ro("lanes", [](const Kernel &k) { return k.lanes(); })
        .def("lane", [](Kernel &k, int i) -> Lane & { return k.lane(i); }, "index"_a, nb::rv_policy::reference_internal)
        .def_prop_ro("density_lookups", [](const Kernel &k) { return k.density_lookups(); });
    if constexpr (has_film<Kernel>::value) {
        cls.def("image", [](const Kernel &k) { return film_image(k.film()); })
            .def_prop_ro("samples_per_pixel", [](const Kernel &k) { return k.film().samples_per_pixel; })
            .def_prop_ro("nonfinite", [](const Kernel &k) { return k.film().nonfinite; });
    }
    return cls;
}

// Probes of a phase function for tests: what the renderer samples from uniform
// numbers u (n, 2), and the density it evaluates for directions wi (n, 3).
inline auto probe_phase_sample(const Phase &ph, const V3 &wo, Array<double> u) {
    size_t n = u.shape(0);
    std::vector<double> wi(3 * n), pdf(n);
    Vec3 w = normalize(vec(wo));
    for (size_t i = 0; i < n; ++i) {
        double p;
        Vec3 d = phase_sample(ph, w, u.data()[2 * i], u.data()[2 * i + 1], p);
        for (int a = 0; a < 3; ++a) wi[3 * i + a] = d[a];
        pdf[i] = p;
    }
    return std::make_tuple(to_numpy(std::move(wi), {n, 3}), to_numpy(std::move(pdf), {n}));
}

inline auto probe_phase_eval(const Phase &ph, const V3 &wo, Array<double> wi) {
    size_t n = wi.shape(0);
    std::vector<double> out(n);
    Vec3 w = normalize(vec(wo));
    for (size_t i = 0; i < n; ++i)
        out[i] = phase_eval(ph, w, Vec3(wi.data()[3 * i], wi.data()[3 * i + 1], wi.data()[3 * i + 2]));
    return to_numpy(std::move(out), {n});
}

// Each binding file registers its function here (PGI_BINDING), and the module calls them
// all, in the order of their names: a new file needs no line anywhere else.
using Binder = void (*)(nb::module_ &);
inline std::vector<std::pair<std::string, Binder>> &binders() {
    static std::vector<std::pair<std::string, Binder>> all;
    return all;
}
struct RegisterBinding {
    RegisterBinding(const char *name, Binder bind) { binders().emplace_back(name, bind); }
};
#define PGI_BINDING(name, function) static const ::pgi::bind::RegisterBinding pgi_binding_##function(name, function)

}  // namespace pgi::bind
