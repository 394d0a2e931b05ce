#pragma once
// What the renderer's pass tests measure on a render: finiteness, luminance, the relative
// difference of two layers over a mask, the car's mean luminance (over its pixels, or over those
// that see a given plane), and a render on both devices held finite, in range and agreeing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/mat4x4.hpp>
#include <vector>

#include "engine/lighting/sg_lighting.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/scene/gltf_scene.h"
#include "engine/sphere/equirect.h"

namespace odvr::testing {

inline bool AllFinite(const sphere::EquirectImage& img) {
  return std::all_of(img.rgb.begin(), img.rgb.end(), [](float v) { return std::isfinite(v); });
}

inline double Luma(const float* c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

struct Diff {
  double mean_rel = 0, p99_rel = 0, max_rel = 0;
  int pixels = 0;
};

// Relative luminance differences of `a` to `b` over the pixels where `mask` > 0.5.
inline Diff Compare(const sphere::EquirectImage& a, const sphere::EquirectImage& b, const std::vector<float>& mask,
                    double floor = 1e-3) {
  std::vector<double> rel;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (mask[i] <= 0.5f) continue;
    const double la = Luma(&a.rgb[3 * i]), lb = Luma(&b.rgb[3 * i]);
    rel.push_back(std::abs(la - lb) / std::max(lb, floor));
  }
  Diff d;
  d.pixels = static_cast<int>(rel.size());
  if (rel.empty()) return d;
  for (double r : rel) d.mean_rel += r;
  d.mean_rel /= static_cast<double>(rel.size());
  std::sort(rel.begin(), rel.end());
  d.p99_rel = rel[static_cast<std::size_t>(0.99 * static_cast<double>(rel.size() - 1))];
  d.max_rel = rel.back();
  return d;
}

// Mean of the car layer's luminance over covered pixels.
inline double MeanCarLuma(const render::RenderResult& r) {
  double sum = 0;
  int n = 0;
  for (std::size_t i = 0; i < r.car_alpha.size(); ++i)
    if (r.car_alpha[i] > 0.5f) {
      sum += Luma(&r.car.rgb[3 * i]);
      ++n;
    }
  return n ? sum / n : 0;
}

// Mean luminance (channels summed) of the car pixels whose ray meets the plane y = plane_y in
// front of the camera within x in [x0, x1], |z| <= z_half; at least 50 of them expected.
inline double MeanOnPlane(const render::PinholeCamera& view, const render::RenderResult& r, double plane_y, double x0,
                          double x1, double z_half) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < view.height; ++y)
    for (int x = 0; x < view.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * view.width + x;
      const glm::dvec3 d = view.Ray(x + 0.5, y + 0.5);
      const double t = (plane_y - view.position.y) / d.y;
      if (r.car_alpha[i] < 0.5f || !(t > 0) || std::isinf(t)) continue;
      const glm::dvec3 p = view.position + t * d;
      if (p.x < x0 || p.x > x1 || std::abs(p.z) > z_half) continue;
      sum += r.car.rgb[3 * i] + r.car.rgb[3 * i + 1] + r.car.rgb[3 * i + 2];
      ++n;
    }
  EXPECT_GT(n, 50);
  return sum / std::max(n, 1);
}

// Renders `model` on both devices under the sunny sky and checks every layer is finite and
// in range; returns the GPU result.
inline render::RenderResult RenderBothFinite(const scene::GltfScene& model, const render::RenderOptions& o,
                                             const lighting::SgLighting& light, const render::PinholeCamera& cam,
                                             const char* what) {
  render::TripleProductRenderer r(model, glm::dmat4(1.0), o);
  r.SetLighting(light);
  render::RenderResult gpu = r.Render(cam, render::ShadeDevice::kGpu);
  const render::RenderResult cpu = r.Render(cam, render::ShadeDevice::kCpu);
  for (const render::RenderResult* res : {static_cast<const render::RenderResult*>(&gpu), &cpu}) {
    EXPECT_TRUE(AllFinite(res->car)) << what;
    EXPECT_TRUE(AllFinite(res->shadow)) << what;
    EXPECT_TRUE(AllFinite(res->composite)) << what;
    EXPECT_GE(*std::min_element(res->car.rgb.begin(), res->car.rgb.end()), 0.f) << what;
    for (float v : res->shadow.rgb) {
      EXPECT_GE(v, 0.f) << what;
      EXPECT_LE(v, 1.f) << what;
    }
  }
  const Diff d = Compare(gpu.car, cpu.car, gpu.car_alpha, 1e-2);
  std::printf("%s: %d car px, GPU vs CPU mean relative %.4f\n", what, d.pixels, d.mean_rel);
  EXPECT_LT(d.mean_rel, 0.03) << what;
  return gpu;
}

}  // namespace odvr::testing
