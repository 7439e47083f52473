// Bindings of the media options (transmittance estimator, tabulated phase
// functions) and probes of the media estimators and phase sampling for tests
// and benchmarks (see medium.h, phase.h).
#include "bindings.h"

namespace pgi::bind {

using namespace nb::literals;

namespace {

std::shared_ptr<const PhaseTable> table_of(Array<double> values) {
    return std::make_shared<const PhaseTable>(std::vector<double>(values.data(), values.data() + values.size()));
}

Medium &medium_at(Scene &s, int medium) {
    if (medium < 0 || size_t(medium) >= s.media.size()) throw std::out_of_range("no such medium");
    return s.media[medium];
}

}  // namespace

static void bind_media(nb::module_ &m) {
    m.def("configure_medium",
          [](Scene &s, int medium, Estimator estimator, double march_step) {
              Medium &md = medium_at(s, medium);
              md.estimator = estimator;
              md.march_step = march_step;
          }, "scene"_a, "medium"_a, "estimator"_a, "march_step"_a);
    m.def("set_phase_table",
          [](Scene &s, int medium, Array<double> values) {
              Medium &md = medium_at(s, medium);
              md.phase.type = PhaseType::Tabulated;
              md.phase.table = table_of(values);
          }, "scene"_a, "medium"_a, "values"_a);
    m.def("grid_bounds",
          [](const Scene &s, int medium) {
              const DensityGrid &g = s.media.at(medium).grid;
              std::vector<double> hi(g.majorants.begin(), g.majorants.end()), lo(g.minorants.begin(), g.minorants.end());
              size_t z = g.mz, y = g.my, x = g.mx;
              return std::make_tuple(to_numpy(std::move(hi), {z, y, x}), to_numpy(std::move(lo), {z, y, x}));
          }, "scene"_a, "medium"_a);
    // Per-sample transmittance estimates (gray) and the total density lookups:
    // the variance and cost of an estimator, for efficiency comparisons.
    m.def("transmittance_samples",
          [](const Scene &s, int medium, V3 origin, V3 direction, double tmax, uint64_t seed, int64_t n) {
              std::vector<double> out(n);
              MediumStats st;
              Vec3 o = vec(origin), d = normalize(vec(direction));
              const Medium &md = s.media.at(medium);
              released([&] {
                  for (int64_t i = 0; i < n; ++i) {
                      Sampler rng(stream_key(seed, uint64_t(i), 0x7472));
                      out[i] = transmittance(md, o, d, tmax, rng, st).x;
                  }
              });
              return std::make_tuple(to_numpy(std::move(out), {size_t(n)}), st.density_lookups);
          }, "scene"_a, "medium"_a, "origin"_a, "direction"_a, "tmax"_a, "seed"_a, "n"_a);
    m.def("sample_phase_table",
          [](Array<double> values, V3 wo, Array<double> u) {
              Phase ph{PhaseType::Tabulated, 0.0, table_of(values)};
              return probe_phase_sample(ph, wo, u);
          }, "values"_a, "wo"_a, "u"_a);
    m.def("eval_phase_table",
          [](Array<double> values, V3 wo, Array<double> wi) {
              Phase ph{PhaseType::Tabulated, 0.0, table_of(values)};
              return probe_phase_eval(ph, wo, wi);
          }, "values"_a, "wo"_a, "wi"_a);
}

PGI_BINDING("media", bind_media);

}  // namespace pgi::bind
