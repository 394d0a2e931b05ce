#include "engine/material/brdf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "core/constants.h"
#include "core/error.h"

namespace odvr::material {
namespace {

using lighting::RgbSg;
using lighting::Sg;

// ∫ f over the sphere in (u = 1 − cos θ, φ) around `pole`: u on a geometric grid from 1e-9 to 2
// (dense near the pole, where a λ = 10⁴ lobe is 0.01 rad wide), midpoint rule in both.
template <class F>
glm::dvec3 PoleQuadrature(const F& f, const glm::dvec3& pole, int n_u, int n_phi) {
  const glm::dvec3 t = std::abs(pole.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 e1 = glm::normalize(glm::cross(pole, t)), e2 = glm::cross(pole, e1);
  glm::dvec3 sum(0);
  double u_prev = 0;
  for (int i = 1; i <= n_u; ++i) {
    const double u = 2.0 * std::pow(1e-9 / 2.0, 1.0 - double(i) / n_u);
    const double um = 0.5 * (u_prev + u), du = u - u_prev;
    const double cos_t = 1 - um, sin_t = std::sqrt(std::max(0.0, 1 - cos_t * cos_t));
    glm::dvec3 ring(0);
    for (int j = 0; j < n_phi; ++j) {
      const double phi = 2 * kPi * (j + 0.5) / n_phi;
      ring += f(cos_t * pole + sin_t * (std::cos(phi) * e1 + std::sin(phi) * e2));
    }
    sum += ring * (du * 2 * kPi / n_phi);
    u_prev = u;
  }
  return sum;
}

// The integrand has two sharp places, the light's axis and the BRDF's peak; each gets its own
// pole grid, split by a smooth partition of unity so neither grid sees the other's spike.
template <class F>
glm::dvec3 TwoPoleQuadrature(const F& f, const glm::dvec3& a, const glm::dvec3& b) {
  constexpr double kappa = 20;
  const auto wa = [&](const glm::dvec3& w) {
    return 1.0 / (1.0 + std::exp(kappa * (glm::dot(w, b) - glm::dot(w, a))));
  };
  const int n_u = 800, n_phi = 192;
  return PoleQuadrature([&](const glm::dvec3& w) { return f(w) * wa(w); }, a, n_u, n_phi) +
         PoleQuadrature([&](const glm::dvec3& w) { return f(w) * (1.0 - wa(w)); }, b, n_u, n_phi);
}

// Reference: ∫ f(wi, wo) L(wi) max(0, n·wi) dwi by quadrature of the analytic BRDF.
glm::dvec3 Reference(const Brdf& brdf, const ShadingFrame& fr, const glm::dvec3& wo, const RgbSg& light) {
  const Sg l{light.axis, light.lambda, 1.0};
  const glm::dvec3 mirror = 2.0 * glm::dot(wo, fr.n) * fr.n - wo;
  const auto integrand = [&](const glm::dvec3& wi) {
    const double c = glm::dot(fr.n, wi);
    if (c <= 0) return glm::dvec3(0);
    return Evaluate(brdf, fr, wi, wo) * (c * lighting::Evaluate(l, wi));
  };
  return TwoPoleQuadrature(integrand, light.axis, mirror) * glm::dvec3(light.amplitude);
}

glm::dvec3 ViewAt(const ShadingFrame& fr, double theta_deg) {
  const double t = theta_deg * kPi / 180;
  return std::cos(t) * fr.n + std::sin(t) * fr.t;
}

// Bounds asserted for the default lobes (cosine at the axis, eq. 4.10 warp), a little above what
// was measured (the table the test prints; the numbers in the report of this change).
struct Model {
  std::string name;
  Brdf brdf;
  double aimed_bound;    // light aimed at the mirror direction, views 0°–75°
  double offset_bound;   // light 25° off it towards the normal, views 0°–75°
  double grazing_bound;  // views 85° and 89°, either light
};

struct Errors {
  double aimed = 0, offset = 0, grazing = 0, sum = 0;
  int n = 0;
};

const std::vector<std::pair<std::string, LobeOptions>> kVariants = {
    {"eq4.10, cos at axis", {CosineTerm::kAtLobeAxis, WarpMode::kIsotropic}},
    {"eq4.10, cos as SG", {CosineTerm::kAsSg, WarpMode::kIsotropic}},
    {"split warp, cos at axis", {CosineTerm::kAtLobeAxis, WarpMode::kAnisotropicSplit}},
};

// One model under SG lights of λ = 10, 100, 1000 aimed at the mirror direction and 25° off it
// towards the normal, for views from normal to grazing. The error of a configuration is
// |SG − reference| / max(reference, 1 % of the largest reference of that view): relative where
// the answer is substantial, without letting the near-zero answers of a light far off a sharp
// lobe dominate. Returns one Errors per variant of kVariants.
std::vector<Errors> Measure(const Brdf& brdf) {
  // A tilted normal and tangent, so nothing lines up with the world axes by accident.
  const ShadingFrame fr = ShadingFrame::FromNormal(glm::normalize(glm::dvec3(0.2, 1.0, 0.3)), glm::dvec3(1, 0, 0.1));
  std::vector<Errors> errors(kVariants.size());
  for (double view_deg : {0.0, 30.0, 60.0, 75.0, 85.0, 89.0}) {
    const glm::dvec3 wo = ViewAt(fr, view_deg);
    const glm::dvec3 mirror = 2.0 * glm::dot(wo, fr.n) * fr.n - wo;
    struct Config {
      double off_deg, ref;
      std::vector<double> sg;
    };
    std::vector<Config> configs;
    double peak = 0;
    std::vector<std::vector<Lobe>> lobes;
    for (const auto& v : kVariants) lobes.push_back(Lobes(brdf, fr, wo, v.second));
    for (double light_lambda : {10.0, 100.0, 1000.0}) {
      for (double off_deg : {0.0, 25.0}) {
        const double o = off_deg * kPi / 180;
        // The mirror direction turned by `off` towards the normal (towards t at normal view).
        glm::dvec3 towards = fr.n - glm::dot(fr.n, mirror) * mirror;
        if (glm::length(towards) < 1e-6) towards = fr.t - glm::dot(fr.t, mirror) * mirror;
        const glm::dvec3 axis = std::cos(o) * mirror + std::sin(o) * glm::normalize(towards);
        const RgbSg light{axis, light_lambda, glm::vec3(1.0f, 0.5f, 0.25f)};
        Config c{off_deg, Reference(brdf, fr, wo, light).x, {}};
        for (const auto& l : lobes) {
          const glm::dvec3 sg = ShadeUnderSgLight(l, light);
          EXPECT_TRUE(std::isfinite(sg.x) && std::isfinite(sg.y) && std::isfinite(sg.z));
          c.sg.push_back(sg.x);
        }
        if (std::getenv("ODVR_BRDF_VERBOSE"))
          std::printf("    view %4.1f light lambda %6.0f off %4.1f: ref %.5g sg %.5g / %.5g / %.5g\n", view_deg,
                      light_lambda, off_deg, c.ref, c.sg[0], c.sg[1], c.sg[2]);
        peak = std::max(peak, c.ref);
        configs.push_back(std::move(c));
      }
    }
    for (const Config& c : configs) {
      for (std::size_t v = 0; v < kVariants.size(); ++v) {
        const double err = std::abs(c.sg[v] - c.ref) / std::max(c.ref, 0.01 * peak);
        Errors& e = errors[v];
        if (view_deg >= 85) {
          e.grazing = std::max(e.grazing, err);
          continue;
        }
        (c.off_deg == 0 ? e.aimed : e.offset) = std::max(c.off_deg == 0 ? e.aimed : e.offset, err);
        e.sum += err;
        ++e.n;
      }
    }
  }
  return errors;
}

void MeasureModels(const std::vector<Model>& models) {
  for (const auto& m : models) {
    const std::vector<Errors> errors = Measure(m.brdf);
    for (std::size_t v = 0; v < kVariants.size(); ++v) {
      const Errors& e = errors[v];
      std::printf("  [brdf error] %-28s %-24s aimed %6.2f %%  25deg off %6.2f %%  mean %6.2f %%  grazing %8.2f %%\n",
                  m.name.c_str(), kVariants[v].first.c_str(), 100 * e.aimed, 100 * e.offset, 100 * e.sum / e.n,
                  100 * e.grazing);
    }
    EXPECT_LE(errors[0].aimed, m.aimed_bound) << m.name;
    EXPECT_LE(errors[0].offset, m.offset_bound) << m.name;
    EXPECT_LE(errors[0].grazing, m.grazing_bound) << m.name;
  }
}

// The diffuse lobe is the clamped cosine itself (ClampedCosineMean): what is left is the
// table's interpolation.
// GGX's power-law tail under a sharp light off the mirror direction (the studio softbox on the
// glossy paint's hood, docs/notes/render_accuracy.md): the lobes alone hold a few percent of it, the lobes
// plus GgxResidualUnderSgLight (what the renderer adds per peak, clamped at 0) follow quadrature.
// Light λ = 1000 (the softbox's peak SG: 1076), views 30–80°, the light 0–45° off the mirror
// direction towards the normal and sideways.
TEST(Brdf, GgxResidualRecoversTheTailUnderASharpLight) {
  const ShadingFrame fr = ShadingFrame::FromNormal(glm::normalize(glm::dvec3(0.2, 1.0, 0.3)), glm::dvec3(1, 0, 0.1));
  const std::vector<std::pair<std::string, Brdf>> brdfs = {
      {"studio glossy paint", MetallicRoughness{glm::dvec3(0.6), 0.9, 0.25}},
      {"GGX a=0.3", CookTorrance{glm::dvec3(0.9), 0.3, Ndf::kGgx}}};
  for (const auto& [name, brdf] : brdfs) {
    for (const auto& [variant, options] : kVariants) {
      double worst_lobes_far = 0, worst_far = 0, worst_lobes_near = 0, worst_near = 0;
      for (double view_deg : {30.0, 60.0, 80.0}) {
        const glm::dvec3 wo = ViewAt(fr, view_deg);
        const glm::dvec3 mirror = 2.0 * glm::dot(wo, fr.n) * fr.n - wo;
        const std::vector<Lobe> lobes = Lobes(brdf, fr, wo, options);
        glm::dvec3 towards = fr.n - glm::dot(fr.n, mirror) * mirror;
        towards = glm::normalize(towards);
        const glm::dvec3 side = glm::cross(mirror, towards);
        for (double off_deg : {0.0, 5.0, 20.0, 30.0, 45.0}) {
          for (const glm::dvec3& dir : {towards, side}) {
            const double o = off_deg * kPi / 180;
            const glm::dvec3 axis = std::cos(o) * mirror + std::sin(o) * dir;
            if (glm::dot(axis, fr.n) < 0.05) continue;
            const RgbSg light{axis, 1000.0, glm::vec3(1.0f)};
            const double ref = Reference(brdf, fr, wo, light).x;
            const double sg = ShadeUnderSgLight(lobes, light).x;
            const double with =
                std::max(0.0, sg + GgxResidualUnderSgLight(brdf, fr, wo, lobes, Sg{axis, 1000.0, 1.0}).x);
            const double err_lobes = std::abs(sg - ref) / ref, err = std::abs(with - ref) / ref;
            if (std::getenv("ODVR_BRDF_VERBOSE"))
              std::printf("    %s %s view %2.0f off %2.0f: ref %.4g lobes %.4g (%.1f %%) + residual %.4g (%.1f %%)\n",
                          name.c_str(), variant.c_str(), view_deg, off_deg, ref, sg, 100 * err_lobes, with, 100 * err);
            if (off_deg >= 20) {
              worst_lobes_far = std::max(worst_lobes_far, err_lobes);
              worst_far = std::max(worst_far, err);
            } else {
              worst_lobes_near = std::max(worst_lobes_near, err_lobes);
              worst_near = std::max(worst_near, err);
            }
          }
        }
      }
      std::printf(
          "  [ggx residual] %-20s %-24s 20-45deg off: lobes %6.1f %% -> %5.1f %%; 0-5deg off: %6.1f %% -> %5.1f %%\n",
          name.c_str(), variant.c_str(), 100 * worst_lobes_far, 100 * worst_far, 100 * worst_lobes_near,
          100 * worst_near);
      EXPECT_GT(worst_lobes_far, 0.5) << name << ", " << variant;
      EXPECT_LE(worst_far, 0.01) << name << ", " << variant;
      // Near the mirror direction the residual turns within the light; still better than without.
      EXPECT_LE(worst_near, 0.45) << name << ", " << variant;
      EXPECT_LT(worst_near, worst_lobes_near) << name << ", " << variant;
    }
  }
  // Without GGX there is nothing to add.
  const glm::dvec3 wo = ViewAt(fr, 40);
  const Brdf ward = Ward{glm::dvec3(0.5), 0.2, 0.2};
  EXPECT_EQ(GgxResidualUnderSgLight(ward, fr, wo, Lobes(ward, fr, wo), Sg{fr.n, 1000.0, 1.0}), glm::dvec3(0));
}

// The diffuse paint (roughness 1: GGX α = 1, D the constant 1/π) under a sharp light anywhere
// over the hemisphere: its GGX layer's lobe is one constant SG weighted at the mirror direction,
// which lacks the exact layer's n·wi and Smith G, so alone it reads up to 1.3× bright at grazing
// views (2× with the height-correlated G, before the Principled BSDF's separable one); the
// residual restores quadrature's answer (it is what lowered studio_diffuse's bias 0.987 → 0.937,
// docs/notes/render_accuracy.md: the surplus had hidden darkening elsewhere).
TEST(Brdf, GgxResidualIsExactForTheRoughDiffusePaint) {
  const ShadingFrame fr = ShadingFrame::FromNormal(glm::normalize(glm::dvec3(0.2, 1.0, 0.3)), glm::dvec3(1, 0, 0.1));
  const Brdf brdf = MetallicRoughness{glm::dvec3(0.6), 0.0, 1.0};
  for (std::size_t v : {std::size_t{0}, std::size_t{2}}) {
    const auto& [variant, options] = kVariants[v];
    double worst_lobes = 0, worst_sharp = 0, worst_broad = 0;
    for (double view_deg : {0.0, 60.0, 80.0}) {
      const glm::dvec3 wo = ViewAt(fr, view_deg);
      const std::vector<Lobe> lobes = Lobes(brdf, fr, wo, options);
      for (double elevation_deg : {5.0, 30.0, 85.0})
        for (double azimuth_deg : {0.0, 180.0}) {
          const double t = (90 - elevation_deg) * kPi / 180, p = azimuth_deg * kPi / 180;
          const glm::dvec3 axis = std::cos(t) * fr.n + std::sin(t) * (std::cos(p) * fr.t + std::sin(p) * fr.b);
          for (double lambda : {100.0, 1000.0}) {
            const RgbSg light{axis, lambda, glm::vec3(1.0f)};
            const double ref = Reference(brdf, fr, wo, light).x;
            const double sg = ShadeUnderSgLight(lobes, light).x;
            const double with =
                std::max(0.0, sg + GgxResidualUnderSgLight(brdf, fr, wo, lobes, Sg{axis, lambda, 1.0}).x);
            const double err_lobes = std::abs(sg - ref) / ref, err = std::abs(with - ref) / ref;
            if (std::getenv("ODVR_BRDF_VERBOSE"))
              std::printf(
                  "    %s view %2.0f light %2.0f/%3.0f deg λ %4.0f: ref %.4g lobes %+.1f %% + residual %+.1f %%\n",
                  variant.c_str(), view_deg, elevation_deg, azimuth_deg, lambda, ref, 100 * (sg / ref - 1),
                  100 * (with / ref - 1));
            worst_lobes = std::max(worst_lobes, err_lobes);
            (lambda >= 1000 ? worst_sharp : worst_broad) = std::max(lambda >= 1000 ? worst_sharp : worst_broad, err);
          }
        }
    }
    std::printf("  [ggx residual] diffuse paint %-24s lobes %6.1f %% -> λ 1000 %5.2f %%, λ 100 %5.2f %%\n",
                variant.c_str(), 100 * worst_lobes, 100 * worst_sharp, 100 * worst_broad);
    EXPECT_GT(worst_lobes, 0.25) << variant;
    EXPECT_LE(worst_sharp, 0.005) << variant;
    // λ 100 at 5° elevation and an 80° view: the 7-point rule spans the horizon's cut (5.2 %).
    EXPECT_LE(worst_broad, 0.06) << variant;
  }
}

TEST(Brdf, LambertianSgShadingMatchesQuadrature) {
  MeasureModels({{"Lambertian", Lambertian{glm::dvec3(0.7)}, 0.002, 0.002, 0.008}});
}

// ClampedCosineMean and ClampedCosineGrazingMean, the table and the narrow-Gaussian forms beyond
// it, against quadrature of ∫ G max(0, n·w) / ∫ G (and with FL = (1 − n·w)⁵), from a constant
// light to a sun, the axis from the normal to the nadir. Errors are relative where the mean is at
// least 5 % of its largest value (1, and 1/21 with FL), absolute below.
TEST(Brdf, ClampedCosineMeanMatchesQuadrature) {
  const glm::dvec3 n = glm::normalize(glm::dvec3(0.2, 1.0, 0.3));
  const ShadingFrame fr = ShadingFrame::FromNormal(n);
  double worst_rel = 0, worst_abs = 0, fl_worst_rel = 0, fl_worst_abs = 0;
  for (double lambda : {0.0, 0.3, 1.0, 2.133, 5.0, 13.0, 40.0, 63.9, 64.0, 150.0, 1000.0}) {
    for (double theta_deg : {0.0, 20.0, 45.0, 60.0, 75.0, 85.0, 90.0, 95.0, 110.0, 180.0}) {
      const double t = theta_deg * kPi / 180;
      const glm::dvec3 axis = std::cos(t) * n + std::sin(t) * fr.t;
      const Sg g{axis, lambda, 1.0};
      const double ref =
          PoleQuadrature(
              [&](const glm::dvec3& w) { return glm::dvec3(std::max(0.0, glm::dot(n, w)) * lighting::Evaluate(g, w)); },
              axis, 800, 256)
              .x /
          lighting::Integral(g);
      const double got = ClampedCosineMean(std::cos(t), lambda);
      const double fl_ref = PoleQuadrature(
                                [&](const glm::dvec3& w) {
                                  const double c = std::max(0.0, glm::dot(n, w));
                                  return glm::dvec3(c * std::pow(1 - c, 5.0) * lighting::Evaluate(g, w));
                                },
                                axis, 800, 256)
                                .x /
                            lighting::Integral(g);
      const double fl_got = ClampedCosineGrazingMean(std::cos(t), lambda);
      ASSERT_TRUE(std::isfinite(fl_got));
      EXPECT_GE(fl_got, 0.0);
      if (fl_ref >= 0.05 / 21) {
        fl_worst_rel = std::max(fl_worst_rel, std::abs(fl_got / fl_ref - 1));
      } else {
        fl_worst_abs = std::max(fl_worst_abs, std::abs(fl_got - fl_ref));
      }
      ASSERT_TRUE(std::isfinite(got));
      EXPECT_GE(got, 0.0);
      if (ref >= 0.05) {
        worst_rel = std::max(worst_rel, std::abs(got / ref - 1));
      } else {
        worst_abs = std::max(worst_abs, std::abs(got - ref));
      }
      EXPECT_NEAR(ClampedCosineIntegral(n, {axis, lambda, 2.5}), 2.5 * got * lighting::Integral(g), 1e-12 * (1 + got));
    }
  }
  std::printf("  [clamped cosine] worst %.3f %% relative (mean >= 0.05), %.2e absolute below\n", 100 * worst_rel,
              worst_abs);
  std::printf("  [clamped cosine FL] worst %.3f %% relative (mean >= 0.05/21), %.2e absolute below\n",
              100 * fl_worst_rel, fl_worst_abs);
  EXPECT_LE(fl_worst_rel, 0.025);                                   // measured 1.72 %, beyond the table
  EXPECT_LE(fl_worst_abs, 5e-5);                                    // measured 2.1·10⁻⁵
  EXPECT_NEAR(ClampedCosineGrazingMean(0.3, 0.0), 1.0 / 84, 2e-5);  // (1/4π) ∫ c FL = 1/84
  EXPECT_LE(worst_rel, 0.005);                                      // measured 0.33 %
  EXPECT_LE(worst_abs, 1e-3);                                       // measured 4.8·10⁻⁴
  // The limits: a constant light's mean is 1/4 (π over 4π), a sun's the cosine itself.
  EXPECT_NEAR(ClampedCosineMean(0.3, 0.0), 0.25, 2e-5);  // the table's quadrature: 6·10⁻⁶
  EXPECT_NEAR(ClampedCosineMean(0.5, 1e5), 0.5, 1e-4);
  EXPECT_NEAR(ClampedCosineMean(-0.5, 1e5), 0.0, 1e-12);
}

TEST(Brdf, PhongSgShadingMatchesQuadrature) {
  MeasureModels({{"Phong n=10", Phong{glm::dvec3(1), 10}, 0.09, 0.62, 1.0},
                 {"Phong n=100", Phong{glm::dvec3(1), 100}, 0.02, 0.36, 0.95},
                 {"Phong n=10000", Phong{glm::dvec3(1), 10000}, 0.001, 0.003, 0.035}});
}

TEST(Brdf, BlinnPhongSgShadingMatchesQuadrature) {
  MeasureModels({{"Blinn-Phong s=20", BlinnPhong{glm::dvec3(1), 20}, 0.14, 0.92, 1.001},
                 {"Blinn-Phong s=500", BlinnPhong{glm::dvec3(1), 500}, 0.23, 0.81, 1.001}});
}

TEST(Brdf, WardSgShadingMatchesQuadrature) {
  MeasureModels({{"Ward iso a=0.1", Ward{glm::dvec3(0.5), 0.1, 0.1}, 0.24, 0.99, 1.35},
                 {"Ward iso a=0.3", Ward{glm::dvec3(0.5), 0.3, 0.3}, 0.22, 0.87, 1.001},
                 {"Ward aniso 0.05x0.2", Ward{glm::dvec3(0.5), 0.05, 0.2}, 0.53, 0.16, 0.86},
                 {"Ward aniso 0.3x0.1", Ward{glm::dvec3(0.5), 0.3, 0.1}, 0.08, 0.44, 0.76}});
}

// GGX as two SGs (GgxSg) against the one SG it replaced, eq. 4.10 (split warp): α = 0.05 aimed
// 48 → 29 % (28 → 14 %), α = 0.3 aimed 52 → 37 % (30 → 20 %), 25° off 71 → 77 % (41 → 24 %);
// α = 0.7 is past the fade, one SG as before. The split warp got worse in three places (not
// asserted here; the bounds are eq. 4.10's): α = 0.05 25° off 94 → 96 %, and the glTF paint and
// metal below. The cause is the tail SG, 45 % of D, warped by eq. 4.10 alone: too narrow in the
// plane of incidence, where the light 25° off lies (and too wide across it). Splitting the tail
// too was measured: α = 0.05 25° off 55 %, glTF paint aimed 8.3 %, 25° off 5.5 %, glTF metal
// 25° off 18 %; it costs the renderer a second split row of lobes per glossy pixel, so not yet.
TEST(Brdf, CookTorranceSgShadingMatchesQuadrature) {
  MeasureModels(
      {{"Cook-Torrance GGX a=0.05", CookTorrance{glm::dvec3(0.9), 0.05, Ndf::kGgx}, 0.30, 0.98, 1.1},
       {"Cook-Torrance GGX a=0.3", CookTorrance{glm::dvec3(0.9), 0.3, Ndf::kGgx}, 0.39, 0.78, 1.8},
       {"Cook-Torrance GGX a=0.7", CookTorrance{glm::dvec3(0.9), 0.7, Ndf::kGgx}, 0.38, 0.37, 1.0},
       {"Cook-Torrance Beckmann m=0.1", CookTorrance{glm::dvec3(0.9), 0.1, Ndf::kBeckmann}, 0.24, 0.98, 1.77},
       {"Cook-Torrance Beckmann m=0.4", CookTorrance{glm::dvec3(0.9), 0.4, Ndf::kBeckmann}, 0.34, 0.61, 1.15}});
}

// The rough paint's bounds are the principled diffuse's: its grazing-light terms (FL, Burley's
// darkening and retro-reflection for light near the horizon) reach the lobe only through the
// directional albedo, so a sharp light at 75° off the normal sees them averaged (35 % aimed).
// Split warp, one SG → two for D: glTF paint r = 0.4 aimed 21 → 26 %, 25° off 9.0 → 12 %; glTF
// metal r = 0.3 aimed 31 → 14 %, 25° off 72 → 84 % (the tail's eq. 4.10 warp, see above).
// The Principled BSDF's Fresnel instead of Schlick's (material::Fresnel::kPrincipled), taken at each
// lobe's axis and steeper than Schlick's between 40° and 70°: glTF paint 25° off 27 → 36 % (eq.
// 4.10; split warp 12 → 19 %), aimed 40 → 37 %, the metal within 0.1 point, the rough paint better
// by 2–3 points; against Cycles every reference's error fell (docs/notes/render_accuracy.md).
TEST(Brdf, MetallicRoughnessSgShadingMatchesQuadrature) {
  MeasureModels({{"glTF paint r=0.4 m=0", MetallicRoughness{glm::dvec3(0.6, 0.1, 0.1), 0.0, 0.4}, 0.41, 0.37, 2.15},
                 {"glTF metal r=0.3 m=1", MetallicRoughness{glm::dvec3(0.9, 0.8, 0.6), 1.0, 0.3}, 0.27, 0.9, 1.6},
                 {"glTF rough r=0.9 m=0", MetallicRoughness{glm::dvec3(0.5), 0.0, 0.9}, 0.36, 0.20, 1.05}});
}

// Fresnel::kPrincipled against the Fresnel equations themselves (Snell's law, s and p
// polarizations averaged) for a dielectric of IOR 1.5: at f0 = 0.04, the Principled BSDF's
// specular 0.5, it is that reflectance; at another f0 the same curve remapped from 0.04 to f0.
// Schlick's (1 − cos)⁵ is 16–23 % low at 45–65° there, which is what the change is for.
TEST(Brdf, PrincipledFresnelIsTheDielectricsRemapped) {
  const double eta = 1.5;
  const auto fresnel_equations = [&](double cos_i) {
    const double sin_t = std::sqrt(1.0 - cos_i * cos_i) / eta, cos_t = std::sqrt(1.0 - sin_t * sin_t);
    const double rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t), rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
  };
  for (double deg = 0; deg <= 89.5; deg += 2.5) {
    const double c = std::cos(deg * kPi / 180), fd = fresnel_equations(c);
    EXPECT_NEAR(FresnelOf(Fresnel::kPrincipled, glm::dvec3(0.04), c).x, fd, 1e-12) << deg;
    const glm::dvec3 metal = FresnelOf(Fresnel::kPrincipled, glm::dvec3(0.9, 0.6, 0.3), c);
    EXPECT_NEAR(metal.y, 0.6 + 0.4 * (fd - 0.04) / 0.96, 1e-12) << deg;
  }
  EXPECT_NEAR(FresnelOf(Fresnel::kPrincipled, glm::dvec3(0.04), 0.0).x, 1.0, 1e-12);
  const double c60 = 0.5, schlick60 = FresnelOf(Fresnel::kSchlick, glm::dvec3(0.04), c60).x;
  EXPECT_NEAR(schlick60, 0.04 + 0.96 / 32, 1e-12);
  EXPECT_GT(fresnel_equations(c60) / schlick60, 1.25);
}

// A metal's metallic-roughness BRDF against Cycles 3.x's GGX reflection as it writes it
// (bsdf_microfacet_ggx_eval_reflect: D = α²/(π cos⁴θm (α² + tan²θm)²), G1 = 2/(1 + √(1 + α²
// tan²θ)) for each direction, their product, and the Principled Fresnel at wo·h), rewritten here
// apart from the code under test. The height-correlated G it replaced would read 1.18× this with
// view and light both at 80° (the same formulas, worked by hand), far outside the tolerance.
TEST(Brdf, MetallicRoughnessSpecularIsCyclesGgx) {
  const ShadingFrame fr = ShadingFrame::FromNormal(glm::normalize(glm::dvec3(0.1, 1.0, -0.2)), glm::dvec3(1, 0, 0));
  const glm::dvec3 base(0.9, 0.6, 0.3);
  const double roughness = 0.6, a2 = std::pow(roughness, 4);
  const auto g1 = [&](double c) { return 2.0 / (1.0 + std::sqrt(1.0 + a2 * (1.0 - c * c) / (c * c))); };
  double worst = 0;
  for (double view_deg : {0.0, 40.0, 80.0})
    for (double light_deg : {10.0, 50.0, 80.0})
      for (double azimuth_deg : {0.0, 90.0, 180.0}) {
        const glm::dvec3 wo = ViewAt(fr, view_deg);
        const double t = light_deg * kPi / 180, p = azimuth_deg * kPi / 180;
        const glm::dvec3 wi = std::cos(t) * fr.n + std::sin(t) * (std::cos(p) * fr.t + std::sin(p) * fr.b);
        const double ci = glm::dot(fr.n, wi), co = glm::dot(fr.n, wo);
        const glm::dvec3 h = glm::normalize(wi + wo);
        const double cm2 = glm::dot(fr.n, h) * glm::dot(fr.n, h), tan_m2 = (1.0 - cm2) / cm2;
        const double d = a2 / (kPi * cm2 * cm2 * (a2 + tan_m2) * (a2 + tan_m2));
        const glm::dvec3 f = FresnelOf(Fresnel::kPrincipled, base, glm::dot(wo, h));
        const glm::dvec3 cycles = f * (d * g1(ci) * g1(co) * 0.25 / (ci * co));
        const glm::dvec3 ours = Evaluate(MetallicRoughness{base, 1.0, roughness}, fr, wi, wo);
        worst = std::max(worst, std::abs(ours.y / cycles.y - 1.0));
      }
  EXPECT_LT(worst, 1e-9);
}

// The principled diffuse lobe alone (the clamped-cosine lobe of MetallicRoughness) against
// quadrature of c_diff f_d max(0, n·wi) under SG lights from uniform (λ = 0) to a sun, at
// incidences up to 80° on the viewer's side and away from it. Beside it, what the lobe was before
// (the cosine SG fit weighted by f_d's directional albedo): its FL terms averaged, the fit's own
// error on top.
TEST(Brdf, PrincipledDiffuseLobeMatchesQuadrature) {
  const ShadingFrame fr = ShadingFrame::FromNormal(glm::normalize(glm::dvec3(0.2, 1.0, 0.3)), glm::dvec3(1, 0, 0.1));
  double worst = 0, worst_before = 0;
  for (double r : {0.4, 1.0}) {
    const MetallicRoughness paint{glm::dvec3(0.5), 0.0, r};
    for (double view_deg : {0.0, 40.0, 70.0}) {
      const glm::dvec3 wo = ViewAt(fr, view_deg);
      const double mu = glm::dot(fr.n, wo);
      std::vector<Lobe> lobes;
      for (const Lobe& l : Lobes(paint, fr, wo))
        if (l.clamped_cosine) lobes.push_back(l);
      ASSERT_EQ(lobes.size(), 1u);
      const double fv = std::pow(1 - mu, 5.0), a1 = fv * r, a0 = PrincipledDiffuseAlbedo(mu, r) - a1 * 2 * mu / 3;
      const std::vector<Lobe> before = {{CosineSg(fr.n), glm::dvec3(0.5 * a0 / kPi), (a1 / a0) * wo}};
      for (double lambda : {0.0, 3.0, 30.0, 300.0, 3000.0}) {
        for (double incidence_deg : {0.0, 45.0, 80.0}) {
          for (double side : {1.0, -1.0}) {
            const double t = incidence_deg * kPi / 180;
            const glm::dvec3 axis = std::cos(t) * fr.n + side * std::sin(t) * fr.t;
            const RgbSg light{axis, lambda, glm::vec3(1)};
            const Sg g{axis, lambda, 1.0};
            const double ref = PoleQuadrature(
                                   [&](const glm::dvec3& wi) {
                                     const double c = glm::dot(fr.n, wi);
                                     if (c <= 0) return glm::dvec3(0);
                                     return glm::dvec3(0.5 / kPi * c * lighting::Evaluate(g, wi) *
                                                       PrincipledDiffuseFactor(c, mu, glm::dot(wi, wo), r));
                                   },
                                   axis, 800, 256)
                                   .x;
            // Relative to the response to that light at normal incidence, so that grazing
            // lights (whose answer goes to 0) count by what they add to a pixel.
            const double scale = std::max(ref, 0.5 / kPi * ClampedCosineIntegral(fr.n, Sg{fr.n, lambda, 1.0}));
            const double err = std::abs(ShadeUnderSgLight(lobes, light).x - ref) / scale;
            const double err_before = std::abs(ShadeUnderSgLight(before, light).x - ref) / scale;
            worst = std::max(worst, err);
            worst_before = std::max(worst_before, err_before);
            if (std::getenv("ODVR_BRDF_VERBOSE"))
              std::printf("    r %.1f view %2.0f lambda %5.0f incidence %+3.0f: error %.2f %% (before %.2f %%)\n", r,
                          view_deg, lambda, side * incidence_deg, 100 * err, 100 * err_before);
          }
        }
      }
    }
  }
  std::printf("  [brdf error] principled diffuse lobe: worst %.2f %% (before: %.2f %%)\n", 100 * worst,
              100 * worst_before);
  EXPECT_LE(worst, 0.02);  // measured 1.44 %: x = wi·wo at the SG product's mean direction, uniform light
}

// The closed-form directional albedo of the principled diffuse against quadrature of the factor
// itself, over views and roughnesses; and the factor's own limits: Lambert (1) at normal view
// and light, Burley's f_d90 = 1/2 + 2 r cos²θ_d at grazing light and view.
TEST(Brdf, PrincipledDiffuseAlbedoMatchesQuadrature) {
  const ShadingFrame fr = ShadingFrame::FromNormal(glm::dvec3(0, 1, 0));
  for (double r : {0.0, 0.4, 1.0}) {
    for (double view_deg : {0.0, 30.0, 60.0, 78.0, 89.0}) {
      const glm::dvec3 wo = ViewAt(fr, view_deg);
      const double cos_o = glm::dot(fr.n, wo);
      const glm::dvec3 q = PoleQuadrature(
          [&](const glm::dvec3& wi) {
            const double c = glm::dot(fr.n, wi);
            return glm::dvec3(c > 0 ? PrincipledDiffuseFactor(c, cos_o, glm::dot(wi, wo), r) * c : 0.0);
          },
          fr.n, 400, 400);
      EXPECT_NEAR(PrincipledDiffuseAlbedo(cos_o, r), q.x / kPi, 2e-3) << "r " << r << " view " << view_deg;
    }
  }
  EXPECT_DOUBLE_EQ(PrincipledDiffuseFactor(1, 1, 1, 1.0), 1.0);
  EXPECT_NEAR(PrincipledDiffuseFactor(0, 0, -1, 0.7), 0.25, 1e-12);  // fd90 = 1/2 at θ_d = 90°, squared
  EXPECT_NEAR(PrincipledDiffuseFactor(0, 0, 1, 0.7), (0.5 + 2 * 0.7) * (0.5 + 2 * 0.7), 1e-12);
}

// Hard case: a mirror-like Phong lobe (λ = 10⁴) under a light as sharp (λ sums to 2·10⁴), from
// normal to 89.99°: finite, non-negative, and still the quadrature's answer where it has one.
TEST(Brdf, PhongTenThousandStaysFiniteAndAccurate) {
  const ShadingFrame fr = ShadingFrame::FromNormal(glm::dvec3(0, 1, 0));
  const Brdf phong = Phong{glm::dvec3(1), 10000};
  for (double view_deg : {0.0, 45.0, 89.0, 89.99, 90.0, 95.0}) {
    const glm::dvec3 wo = ViewAt(fr, view_deg);
    const auto lobes = Lobes(phong, fr, wo);
    for (const Lobe& l : lobes) {
      EXPECT_TRUE(std::isfinite(l.sg.lambda) && std::isfinite(l.sg.amplitude) && std::isfinite(l.weight.x));
    }
    const glm::dvec3 mirror = 2.0 * glm::dot(wo, fr.n) * fr.n - wo;
    const RgbSg light{glm::normalize(mirror + 0.3 * fr.n * (view_deg >= 89 ? 0.01 : 0.0)), 1e4, glm::vec3(1)};
    const glm::dvec3 sg = ShadeUnderSgLight(lobes, light);
    EXPECT_TRUE(std::isfinite(sg.x) && sg.x >= 0) << view_deg;
    if (view_deg <= 45) {
      const double ref = Reference(phong, fr, wo, light).x;
      std::printf("  [brdf error] Phong n=10000, light lambda 1e4, view %4.1f: sg %.6g ref %.6g (%.3f %%)\n", view_deg,
                  sg.x, ref, 100 * std::abs(sg.x - ref) / ref);
      EXPECT_NEAR(sg.x / ref, 1.0, 2e-3);  // measured 0.05 %: only cos^n vs e^{n(cos−1)} differs
    }
  }
}

// Hard case: light from below the horizon gives ~0 (the quadrature's answer is < 0.1 % of the
// light from above). The diffuse lobe is the clamped cosine itself (no leak: the SG light's own
// tail above the horizon is all it sees); specular lobes leak only through their own SG tails: measured ≤ 0.8 %
// (Beckmann m = 0.3 at a 60° view, whose warped lobe is broad and near the horizon), ≤ 0.05 % otherwise;
// but GGX's wide tail SG (GgxSg), broad and near the horizon at a 60° view: 1.95 % for glTF r = 0.5.
// That is the lobe itself (its SG reaches below the horizon, where f·cos is 0), not which lighting
// the renderer gives it, so lighting the tail with fewer levels (Lobe::tail_share) leaves it as is.
TEST(Brdf, LightBelowTheHorizonGivesAlmostNothing) {
  const ShadingFrame fr = ShadingFrame::FromNormal(glm::normalize(glm::dvec3(0.2, 1.0, 0.3)), glm::dvec3(1, 0, 0.1));
  const std::vector<std::pair<std::string, Brdf>> models = {
      {"Lambertian", Lambertian{glm::dvec3(0.7)}},
      {"Phong", Phong{glm::dvec3(1), 50}},
      {"Blinn-Phong", BlinnPhong{glm::dvec3(1), 50}},
      {"Ward", Ward{glm::dvec3(0.5), 0.3, 0.1}},
      {"Cook-Torrance", CookTorrance{glm::dvec3(0.9), 0.3, Ndf::kBeckmann}},
      {"glTF", MetallicRoughness{glm::dvec3(0.5), 0.5, 0.5}}};
  for (const auto& [name, brdf] : models) {
    for (double view_deg : {0.0, 60.0}) {
      const glm::dvec3 wo = ViewAt(fr, view_deg);
      const auto lobes = Lobes(brdf, fr, wo);
      const glm::dvec3 mirror = 2.0 * glm::dot(wo, fr.n) * fr.n - wo;
      const double above = std::max(ShadeUnderSgLight(lobes, RgbSg{mirror, 100, glm::vec3(1)}).x,
                                    ShadeUnderSgLight(lobes, RgbSg{fr.n, 100, glm::vec3(1)}).x);
      // 30° below the horizon in the mirror's azimuth, and the nadir.
      glm::dvec3 flat = mirror - glm::dot(mirror, fr.n) * fr.n;
      flat = glm::length(flat) > 1e-6 ? glm::normalize(flat) : fr.t;
      for (const glm::dvec3& axis : {std::cos(kPi / 6) * flat - 0.5 * fr.n, -fr.n}) {
        const RgbSg below{axis, 100, glm::vec3(1)};
        const double sg = ShadeUnderSgLight(lobes, below).x;
        const double ref = Reference(brdf, fr, wo, below).x;
        EXPECT_LE(sg, (name == "glTF" ? 0.025 : 0.01) * above) << name << " view " << view_deg;
        EXPECT_GE(sg, 0.0) << name;
        EXPECT_LE(ref, 1e-3 * above) << name << " (the reference itself)";
      }
    }
  }
}

TEST(Brdf, NdfLambdaKeepsPeakAndNormalisation) {
  EXPECT_NEAR(NdfSgLambda(1.0), 0.0, 1e-9);  // GGX at α = 1 is the constant 1/π
  for (double alpha : {0.01, 0.05, 0.2, 0.5, 0.9}) {
    const double lambda = NdfSgLambda(alpha);
    const Sg d{{0, 1, 0}, lambda, 1.0 / (kPi * alpha * alpha)};
    // ∫ over the upper hemisphere of D(h) (n·h) dh by quadrature: 1 for a normalised NDF.
    const glm::dvec3 hemi =
        PoleQuadrature([&](const glm::dvec3& h) { return glm::dvec3(h.y > 0 ? lighting::Evaluate(d, h) * h.y : 0.0); },
                       glm::dvec3(0, 1, 0), 2000, 8);
    EXPECT_NEAR(hemi.x, 1.0, 1e-3) << alpha;
    if (alpha <= 0.05) {
      EXPECT_NEAR(lambda, 2 / (alpha * alpha) - 1, 1e-2 * lambda) << alpha;
    }
  }
}

// GGX's two SGs: normalised for every α, the peak kept as α → 0 (where Σ w_k = 1), closer to D
// than the one SG of NdfSgLambda over θ_h (the heavy tail) while the fit is whole, and that one
// SG from kGgxSgFadeEnd on.
TEST(Brdf, GgxTwoSgsKeepNormalisationAndFollowTheTail) {
  for (double alpha : {0.01, 0.05, 0.2, 0.3, 0.5, 0.9, 1.0}) {
    const GgxSgFit fit = GgxSg(alpha);
    const auto d2 = [&](const glm::dvec3& h) {
      double v = 0;
      for (int k = 0; k < 2; ++k) v += lighting::Evaluate(Sg{{0, 1, 0}, fit.lambda[k], fit.amplitude[k]}, h);
      return v;
    };
    const glm::dvec3 hemi = PoleQuadrature([&](const glm::dvec3& h) { return glm::dvec3(h.y > 0 ? d2(h) * h.y : 0.0); },
                                           glm::dvec3(0, 1, 0), 2000, 8);
    EXPECT_NEAR(hemi.x, 1.0, 1e-3) << alpha;
    if (alpha <= 0.05) {
      EXPECT_NEAR(d2({0, 1, 0}) * kPi * alpha * alpha, 1.0, 0.01) << alpha;
    }
    if (alpha <= kGgxSgFadeBegin) {
      EXPECT_GT(fit.lambda[0], 4 * fit.lambda[1]) << alpha;
      // D at tan θ_h = 3α: GGX's 1/(1 + 9)² of the peak; one SG gives e^{−9} of it.
      const double t = 3 * alpha, c = 1 / std::sqrt(1 + t * t);
      const glm::dvec3 h{std::sqrt(1 - c * c), c, 0};
      const double a2 = alpha * alpha, ggx = a2 / (kPi * std::pow(c * c * (a2 - 1) + 1, 2));
      const double one = lighting::Evaluate(Sg{{0, 1, 0}, NdfSgLambda(alpha), 1 / (kPi * a2)}, h);
      EXPECT_LT(std::abs(d2(h) - ggx), 0.25 * std::abs(one - ggx)) << alpha;
    }
    // The tail's share of D: Σ w_k/s_k = 1 makes it w_1/s_1 while the fit is whole.
    if (alpha <= kGgxSgFadeBegin) {
      EXPECT_NEAR(GgxTailShare(fit), kGgxSgWeight[1] / kGgxSgLambdaScale[1], 0.01) << alpha;
    }
    if (alpha >= kGgxSgFadeEnd) {
      EXPECT_EQ(GgxTailShare(fit), 0.0) << alpha;
      EXPECT_EQ(fit.amplitude[1], 0.0) << alpha;
      EXPECT_NEAR(fit.lambda[0], NdfSgLambda(alpha), 1e-12) << alpha;
    }
  }
}

// The renderer lights GGX's tail SG with fewer lighting levels (material::Lobe::tail_share): it
// must be the one lobe that says so, after the peak's split row.
TEST(Brdf, OnlyGgxsTailLobeCarriesItsShare) {
  const ShadingFrame fr = ShadingFrame::FromNormal(glm::normalize(glm::dvec3(0.2, 1.0, 0.3)), glm::dvec3(1, 0, 0.1));
  const LobeOptions split{CosineTerm::kAtLobeAxis, WarpMode::kAnisotropicSplit};
  const std::vector<Lobe> lobes = Lobes(MetallicRoughness{glm::dvec3(0.6), 0.9, 0.25}, fr, ViewAt(fr, 60), split);
  ASSERT_GE(lobes.size(), 4u);  // the diffuse lobe, a split row of ≥ 2 peak SGs, the tail
  for (std::size_t i = 0; i + 1 < lobes.size(); ++i) EXPECT_EQ(lobes[i].tail_share, 0.0) << i;
  EXPECT_NEAR(lobes.back().tail_share, kGgxSgWeight[1] / kGgxSgLambdaScale[1], 0.01);
  for (const Lobe& l : Lobes(CookTorrance{glm::dvec3(0.9), 0.1, Ndf::kBeckmann}, fr, ViewAt(fr, 60), split))
    EXPECT_EQ(l.tail_share, 0.0);
  for (const Lobe& l : Lobes(CookTorrance{glm::dvec3(0.9), 0.8, Ndf::kGgx}, fr, ViewAt(fr, 60), split))
    EXPECT_EQ(l.tail_share, 0.0);  // past the fade: one SG
}

TEST(Brdf, WarpAtNormalIncidenceQuartersLambda) {
  const Sg d{glm::normalize(glm::dvec3(0, 1, 1)), 400, 2};
  const Sg w = WarpToIncident(d, d.axis);
  EXPECT_NEAR(glm::length(w.axis - d.axis), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(w.lambda, 100);
  EXPECT_DOUBLE_EQ(w.amplitude, 2);
  // Oblique: the axis is the view mirrored about the lobe axis, λ/(4 cos θ_d).
  const glm::dvec3 wo = glm::normalize(glm::dvec3(0, 1, 0));
  const Sg o = WarpToIncident(d, wo);
  EXPECT_NEAR(glm::dot(o.axis, glm::dvec3(0, 0, 1)), 1.0, 1e-12);
  EXPECT_NEAR(o.lambda, 400 / (4 * std::sqrt(0.5)), 1e-9);
}

// CheckBrdf holds every model to its ranges: the bounds pass, a step past them and NaN do not.
// material::Sheen's albedo table against a Monte-Carlo estimate of ∫ f (n·wi) dwi / colour with
// the analytic BRDF (uniform hemisphere samples, a fixed seed), from normal to grazing views and
// from a satin (0.3) to a felt (1); its lobe reflects exactly colour × E × L under a constant
// light; a zero sheen reflects nothing.
TEST(Brdf, SheenAlbedoMatchesMonteCarloOfTheBrdf) {
  const ShadingFrame fr = ShadingFrame::FromNormal({0, 0, 1});
  std::uint64_t state = 12345;
  const auto uniform = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) * 0x1.0p-53;
  };
  double worst = 0;
  for (double roughness : {0.3, 0.5, 0.8, 1.0}) {
    for (double mu : {1.0, 0.7, 0.4, 0.15}) {
      const glm::dvec3 wo(std::sqrt(1 - mu * mu), 0, mu);
      const Sheen sheen{glm::dvec3(1.0), roughness};
      constexpr int kSamples = 400000;
      double sum = 0;
      for (int k = 0; k < kSamples; ++k) {
        const double z = uniform(), phi = 2 * kPi * uniform(), s = std::sqrt(1 - z * z);
        const glm::dvec3 wi(s * std::cos(phi), s * std::sin(phi), z);
        sum += Evaluate(sheen, fr, wi, wo).x * z;
      }
      const double mc = sum / kSamples * 2 * kPi, table = SheenAlbedo(mu, roughness);
      std::printf("sheen r %.1f, n.wo %.2f: table %.4f, Monte Carlo %.4f\n", roughness, mu, table, mc);
      worst = std::max(worst, std::abs(table - mc));
      const std::vector<Lobe> lobes = Lobes(sheen, fr, wo);
      ASSERT_EQ(lobes.size(), 1u);
      EXPECT_TRUE(lobes[0].clamped_cosine);
      EXPECT_NEAR(lobes[0].weight.x * kPi, table, 1e-12);
    }
  }
  EXPECT_LT(worst, 0.01);
  for (const Lobe& lobe : Lobes(Sheen{glm::dvec3(0), 0.5}, fr, glm::dvec3(0, 0, 1)))
    EXPECT_EQ(lobe.weight, glm::dvec3(0));
}

TEST(Brdf, CheckBrdfRefusesEachParameterPastItsBound) {
  const glm::dvec3 one(1), zero(0);
  for (const Brdf& good : {Brdf{Lambertian{one}}, Brdf{Phong{zero, 0}}, Brdf{Phong{one, 1e5}},
                           Brdf{BlinnPhong{one, 1e5}}, Brdf{Ward{one, 1, 1e-6}}, Brdf{CookTorrance{one, 1e-6}},
                           Brdf{MetallicRoughness{one, 1, 0}}, Brdf{MetallicRoughness{zero, 0, 1}}})
    EXPECT_NO_THROW(CheckBrdf(good));
  const double nan = std::nan("");
  for (const Brdf& bad :
       {Brdf{Lambertian{glm::dvec3(1, 1.01, 1)}}, Brdf{Lambertian{glm::dvec3(nan)}}, Brdf{Phong{one, -1}},
        Brdf{Phong{one, 1e5 + 1}}, Brdf{BlinnPhong{glm::dvec3(-0.1), 10}}, Brdf{Ward{one, 0, 0.5}},
        Brdf{Ward{one, 0.5, 1.5}}, Brdf{CookTorrance{one, 0}}, Brdf{CookTorrance{one, nan}},
        Brdf{MetallicRoughness{one, 1.5, 0.5}}, Brdf{MetallicRoughness{one, 0, -0.5}}}) {
    try {
      CheckBrdf(bad);
      ADD_FAILURE() << "accepted";
    } catch (const odvr::Error& e) {
      EXPECT_NE(std::string(e.what()).find("must be in"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace odvr::material
