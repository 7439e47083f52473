#include "scene.h"

#include <stdexcept>
#include <string>
#include <utility>

namespace pgi {

void Scene::finalize() {
    // Scene size sets the surface offset so that scaled scenes behave alike.
    Vec3 lo(kInf), hi(-kInf);
    for (const Triangle &t : triangles)
        for (const Vec3 &p : {t.p0, t.p0 + t.e1, t.p0 + t.e2})
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], p[a]);
                hi[a] = std::max(hi[a], p[a]);
            }
    if (triangles.empty()) lo = hi = Vec3(0.0);
    scene_center = (lo + hi) * 0.5;
    scene_radius = std::max(1e-30, length(hi - lo) * 0.5);
    ray_epsilon = 1e-5 * scene_radius;
    has_null_surfaces = std::any_of(triangles.begin(), triangles.end(), [&](const Triangle &t) {
        return materials[t.material].type == MaterialType::Null;
    });

    for (AreaEmitter &e : area_emitters) {
        std::vector<double> areas;
        for (int i : e.triangles) areas.push_back(triangles[i].area);
        e.by_area = Distribution1D(areas);
        e.area = e.by_area.total();
    }
    // Pick lights in proportion to an estimate of their power.
    std::vector<double> power;
    light_of_emitter_.assign(area_emitters.size(), -1);
    for (size_t i = 0; i < lights.size(); ++i) {
        const Light &l = lights[i];
        double w = 0;
        switch (l.type) {
            case LightType::Area:
                w = mean(area_emitters[l.emitter].radiance) * area_emitters[l.emitter].area * kPi;
                light_of_emitter_[l.emitter] = int(i);
                break;
            case LightType::Point: w = mean(l.intensity) * 4 * kPi; break;
            case LightType::Spot: w = mean(l.intensity) * 2 * kPi * (1 - std::cos(0.5 * (l.cutoff + l.beam_width))); break;
            case LightType::Directional: w = mean(l.intensity) * kPi * scene_radius * scene_radius; break;
        }
        power.push_back(w);
    }
    light_selection = Distribution1D(power);
    // Vacuum until set_emission_media says otherwise (a scene built by hand, in tests).
    light_emission_medium_.resize(lights.size(), -1);
    triangle_emission_medium_.resize(triangles.size(), -1);
}

void Scene::set_emission_media(std::vector<int> per_triangle, std::vector<int> per_light) {
    if (per_triangle.size() != triangles.size() || per_light.size() != lights.size())
        throw std::invalid_argument("emission media: one entry per triangle and per light expected");
    for (const std::vector<int> *given : {&per_triangle, &per_light})
        for (int m : *given)
            if (m < -1 || m >= int(media.size()))
                throw std::invalid_argument("emission media: no medium " + std::to_string(m));
    triangle_emission_medium_ = std::move(per_triangle);
    light_emission_medium_ = std::move(per_light);
}

int Scene::walk_medium(const Vec3 &p) const {
    const Vec3 start = camera.origin, d = p - start;  // the segment: start + t d, t in [0, 1]
    std::vector<std::pair<double, int>> crossings;  // (t, triangle)
    for (size_t i = 0; i < triangles.size(); ++i) {
        const Triangle &tri = triangles[i];
        if (!tri.transition) continue;
        // Moller-Trumbore, barycentrics and t bounds inclusive.
        const Vec3 pvec = cross(d, tri.e2);
        const double det = dot(tri.e1, pvec);
        if (det == 0) continue;  // the segment runs in the triangle's plane: no crossing
        const double inv = 1 / det;
        const Vec3 tvec = start - tri.p0;
        const double u = dot(tvec, pvec) * inv;
        if (u < 0 || u > 1) continue;
        const Vec3 qvec = cross(tvec, tri.e1);
        const double v = dot(d, qvec) * inv;
        if (v < 0 || u + v > 1) continue;
        const double t = dot(tri.e2, qvec) * inv;
        if (t < 0 || t > 1) continue;
        crossings.emplace_back(t, int(i));
    }
    std::sort(crossings.begin(), crossings.end());
    int medium = camera.medium;
    for (const auto &crossing : crossings)
        medium = triangles[size_t(crossing.second)].medium_after(medium, d);
    return medium;
}

LightSample Scene::sample_light(const Vec3 &p, double u_pick, double u1, double u2, double u3) const {
    LightSample s;
    if (light_selection.size() == 0 || light_selection.total() <= 0) return s;
    size_t li = light_selection.sample(u_pick);
    double pick = light_selection.pmf(li);
    const Light &l = lights[li];
    s.light = int(li);
    switch (l.type) {
        case LightType::Area: {
            const AreaEmitter &e = area_emitters[l.emitter];
            int tri = e.triangles[e.by_area.sample(u1)];
            s.triangle = tri;
            const Triangle &t = triangles[tri];
            double b1, b2;
            square_to_triangle(u2, u3, b1, b2);
            s.point = t.point(b1, b2);
            Vec3 to = s.point - p;
            double d2 = dot(to, to);
            s.dist = std::sqrt(d2);
            s.wi = to / s.dist;
            // The pdf MIS weighs it with (area_light_pdf), from the distance computed here.
            s.pdf = area_pdf_to_solid_angle(pick / e.area, d2, -dot(s.wi, t.n));
            if (!(s.pdf > 0)) return s;
            s.value = e.radiance / s.pdf;
            s.valid = true;
            return s;
        }
        case LightType::Point:
        case LightType::Spot: {
            Vec3 to = l.position - p;
            double d2 = dot(to, to);
            if (d2 <= 0) return s;
            s.point = l.position;
            s.dist = std::sqrt(d2);
            s.wi = to / s.dist;
            double falloff = l.type == LightType::Spot ? l.spot_falloff(-s.wi) : 1.0;
            if (falloff <= 0) return s;
            s.value = l.intensity * (falloff / (d2 * pick));
            s.delta = s.valid = true;
            return s;
        }
        case LightType::Directional: {
            s.wi = -l.direction;
            s.dist = kInf;
            s.value = l.intensity / pick;
            s.delta = s.valid = true;
            return s;
        }
    }
    return s;
}

double Scene::area_light_pdf(int tri, const Vec3 &from, const Vec3 &hit) const {
    const Triangle &t = triangles[tri];
    if (t.emitter < 0) return 0;
    int li = light_of_emitter_[t.emitter];
    Vec3 to = hit - from;
    double d2 = dot(to, to);
    return area_pdf_to_solid_angle(light_selection.pmf(li) / area_emitters[t.emitter].area, d2,
                                   -dot(to, t.n) / std::sqrt(d2));
}

}  // namespace pgi
