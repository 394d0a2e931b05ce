#include "engine/material/brdf.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <sstream>
#include <string>

#include "core/constants.h"
#include "core/error.h"

namespace odvr::material {

using lighting::Sg;

namespace {

glm::dvec3 Reflect(const glm::dvec3& w, const glm::dvec3& about) { return 2.0 * glm::dot(w, about) * about - w; }

// A view at or below the horizon is moved up to n·wo = kMinCosView in its own azimuth (or the
// frame's t when it has none), so both the analytic BRDF and the lobes see the same grazing view.
glm::dvec3 BendView(const ShadingFrame& f, const glm::dvec3& wo) {
  const double c = glm::dot(f.n, wo);
  if (c >= kMinCosView) return wo;
  glm::dvec3 tangential = wo - c * f.n;
  const double l = glm::length(tangential);
  tangential = l > 1e-12 ? tangential / l : f.t;
  return std::sqrt(1.0 - kMinCosView * kMinCosView) * tangential + kMinCosView * f.n;
}

double NdfValue(Ndf ndf, double alpha, double cos_h) {
  if (cos_h <= 0) return 0;
  const double a2 = alpha * alpha, c2 = cos_h * cos_h;
  if (ndf == Ndf::kGgx) {
    const double d = c2 * (a2 - 1.0) + 1.0;
    return a2 / (kPi * d * d);
  }
  return std::exp((c2 - 1.0) / (a2 * c2)) / (kPi * a2 * c2 * c2);
}

// Smith's Λ for a direction at cos θ from n (Heitz 2014); Beckmann through Walter et al. 2007's
// rational fit, which is what every renderer uses and is within 0.4 % of the erf form.
double SmithLambda(Ndf ndf, double alpha, double cos_theta) {
  const double c = std::clamp(cos_theta, 1e-9, 1.0);
  const double tan2 = std::max(0.0, 1.0 - c * c) / (c * c);
  if (ndf == Ndf::kGgx) return 0.5 * (std::sqrt(1.0 + alpha * alpha * tan2) - 1.0);
  if (tan2 <= 0) return 0;
  const double a = 1.0 / (alpha * std::sqrt(tan2));
  if (a >= 1.6) return 0;
  return (1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a);
}

// Height-correlated, or (`separable`, Cycles 3.x's GGX) the product G1(wi) G1(wo).
double SmithG(Ndf ndf, double alpha, double cos_i, double cos_o, bool separable) {
  const double li = SmithLambda(ndf, alpha, cos_i), lo = SmithLambda(ndf, alpha, cos_o);
  return separable ? 1.0 / ((1.0 + li) * (1.0 + lo)) : 1.0 / (1.0 + li + lo);
}

double ClampAlpha(double alpha) { return std::clamp(alpha, kMinAlpha, 1.0); }

struct MrParams {
  glm::dvec3 f0, c_diff;
  double alpha, roughness;
};

MrParams FromMetallicRoughness(const MetallicRoughness& m) {
  const double metallic = std::clamp(m.metallic, 0.0, 1.0);
  const glm::dvec3 base = glm::clamp(m.base_color, 0.0, 1.0);
  const double r = std::clamp(m.roughness, 0.0, 1.0);
  return {glm::mix(glm::dvec3(0.04), base, metallic), base * (1.0 - metallic), ClampAlpha(r * r), r};
}

// Sheen's D V for n·wi, n·wo ≥ 0 and n·h (Sheen's comment).
double CharlieSheen(double n_wi, double n_wo, double n_h, double roughness) {
  const double alpha = std::max(roughness * roughness, kMinSheenAlpha);
  const double sin_h = std::sqrt(std::max(0.0, 1.0 - n_h * n_h));
  const double d = (2.0 + 1.0 / alpha) * std::pow(sin_h, 1.0 / alpha) / (2.0 * kPi);
  return d / (4.0 * std::max(n_wi + n_wo - n_wi * n_wo, 1e-9));
}

// --- Analytic BRDFs (wo already bent, n·wi > 0) --------------------------------------------------

glm::dvec3 Analytic(const Lambertian& m, const ShadingFrame&, const glm::dvec3&, const glm::dvec3&) {
  return m.albedo / kPi;
}

glm::dvec3 Analytic(const Phong& m, const ShadingFrame& f, const glm::dvec3& wi, const glm::dvec3& wo) {
  const double c = glm::dot(Reflect(wo, f.n), wi);
  if (c <= 0) return glm::dvec3(0);
  return m.ks * ((m.exponent + 2.0) / (2.0 * kPi) * std::pow(c, m.exponent));
}

glm::dvec3 Analytic(const BlinnPhong& m, const ShadingFrame& f, const glm::dvec3& wi, const glm::dvec3& wo) {
  const double c = glm::dot(f.n, glm::normalize(wi + wo));
  if (c <= 0) return glm::dvec3(0);
  return m.ks * ((m.exponent + 8.0) / (8.0 * kPi) * std::pow(c, m.exponent));
}

glm::dvec3 Analytic(const Ward& m, const ShadingFrame& f, const glm::dvec3& wi, const glm::dvec3& wo) {
  const glm::dvec3 h = glm::normalize(wi + wo);
  const double hn = glm::dot(h, f.n);
  if (hn <= 0) return glm::dvec3(0);
  const double hx = glm::dot(h, f.t) / m.alpha_x, hy = glm::dot(h, f.b) / m.alpha_y;
  const double e = std::exp(-(hx * hx + hy * hy) / (hn * hn));
  const double cos_i = glm::dot(f.n, wi), cos_o = glm::dot(f.n, wo);
  return m.rho_s * (e / (4.0 * kPi * m.alpha_x * m.alpha_y * std::sqrt(cos_i * cos_o)));
}

glm::dvec3 Analytic(const CookTorrance& m, const ShadingFrame& f, const glm::dvec3& wi, const glm::dvec3& wo) {
  const double alpha = ClampAlpha(m.alpha);
  const glm::dvec3 h = glm::normalize(wi + wo);
  const double cos_i = glm::dot(f.n, wi), cos_o = glm::dot(f.n, wo);
  const double d = NdfValue(m.ndf, alpha, glm::dot(f.n, h));
  const double g = SmithG(m.ndf, alpha, cos_i, cos_o, m.principled);
  return FresnelOf(m.principled ? Fresnel::kPrincipled : Fresnel::kSchlick, m.f0, glm::dot(wi, h)) *
         (d * g / (4.0 * cos_i * cos_o));
}

glm::dvec3 Analytic(const Sheen& m, const ShadingFrame& f, const glm::dvec3& wi, const glm::dvec3& wo) {
  const glm::dvec3 h = wi + wo;
  const double l = glm::length(h);
  const double n_h = l > 1e-12 ? glm::dot(f.n, h) / l : 0.0;
  return m.color * CharlieSheen(glm::dot(f.n, wi), std::max(glm::dot(f.n, wo), 0.0), n_h, m.roughness);
}

glm::dvec3 Analytic(const MetallicRoughness& m, const ShadingFrame& f, const glm::dvec3& wi, const glm::dvec3& wo) {
  const MrParams p = FromMetallicRoughness(m);
  const glm::dvec3 h = glm::normalize(wi + wo);
  const double cos_i = glm::dot(f.n, wi), cos_o = glm::dot(f.n, wo);
  const glm::dvec3 fresnel = FresnelOf(Fresnel::kPrincipled, p.f0, glm::dot(wo, h));
  const double d = NdfValue(Ndf::kGgx, p.alpha, glm::dot(f.n, h));
  const double g = SmithG(Ndf::kGgx, p.alpha, cos_i, cos_o, true);
  const double diffuse = PrincipledDiffuseFactor(cos_i, cos_o, glm::dot(wi, wo), p.roughness);
  return p.c_diff * (diffuse / kPi) + fresnel * (d * g / (4.0 * cos_i * cos_o));
}

// --- Lobes ---------------------------------------------------------------------------------------

// Adds one lobe whose M (everything but D and the cosine) is `m_at_axis`, handling the cosine.
// A lobe whose axis is below the horizon is dropped: M is undefined there, and with the cosine at
// the axis its weight would be 0 anyway.
void Push(const Sg& sg, const glm::dvec3& m_at_axis, const ShadingFrame& f, CosineTerm cosine, std::vector<Lobe>* out) {
  const double cos_axis = glm::dot(f.n, sg.axis);
  if (cos_axis <= 0 || (m_at_axis.x <= 0 && m_at_axis.y <= 0 && m_at_axis.z <= 0)) return;
  if (cosine == CosineTerm::kAtLobeAxis) {
    out->push_back({sg, m_at_axis * cos_axis});
  } else {
    out->push_back({lighting::Product(sg, CosineSg(f.n)), m_at_axis});
  }
}

// A Gaussian exp(−u²/2σL² − v²/2σS²) around `center` (u along the unit tangent `dir`) as a row
// of isotropic SGs of σS. exp(−u²/2σL²) = σL/(σS σc √(2π)) ∫ exp(−τ²/2σc²) exp(−(u−τ)²/2σS²) dτ
// with σc² = σL² − σS², discretised by the trapezoid rule at spacing δ. The integrand in τ is a
// Gaussian of σ_eff = σS σc / σL, whose trapezoid error is 2 exp(−2π² σ_eff²/δ²): δ = 1.8 σ_eff
// keeps it under 0.5 %. Nodes out to ±3σc, at most kMaxAnisotropicLobes of them (then δ grows),
// weights renormalised to the exact integral. emit(axis, λ, amplitude factor) per SG.
template <class Emit>
void SplitRow(const glm::dvec3& center, const glm::dvec3& dir, double s_short, double s_long, Emit&& emit) {
  const double lambda = 1.0 / (s_short * s_short);
  const double s_conv = std::sqrt(std::max(0.0, s_long * s_long - s_short * s_short));
  if (s_conv < 1e-3 * s_short) {
    emit(center, lambda, 1.0);
    return;
  }
  const double s_eff = s_short * s_conv / s_long;
  const int half = std::clamp(int(std::floor(3.0 * s_conv / (1.8 * s_eff))), 1, (kMaxAnisotropicLobes - 1) / 2);
  const double delta = 3.0 * s_conv / half;
  double sum = 0;
  for (int k = -half; k <= half; ++k) sum += std::exp(-(k * delta) * (k * delta) / (2.0 * s_conv * s_conv));
  const double scale = (s_long / s_short) / sum;
  for (int k = -half; k <= half; ++k) {
    const double tau = k * delta;
    emit(glm::normalize(center + tau * dir), lambda, scale * std::exp(-tau * tau / (2.0 * s_conv * s_conv)));
  }
}

// Warps the half-vector lobe `d` to incident space (eq. 4.10, or split, see WarpMode) and adds
// it with M evaluated at each resulting axis: m_of(wi) is M(wi, wo) with h = normalize(wi + wo).
template <class MOf>
void PushWarped(const Sg& d, MOf&& m_of, const ShadingFrame& f, const glm::dvec3& wo, const LobeOptions& o,
                std::vector<Lobe>* out) {
  const Sg w = WarpToIncident(d, wo);
  const glm::dvec3 across = d.axis - glm::dot(d.axis, w.axis) * w.axis;  // in the plane of incidence
  if (o.warp == WarpMode::kIsotropic || glm::length(across) < 1e-9 || d.lambda <= 0) {
    Push(w, m_of(w.axis), f, o.cosine, out);
    return;
  }
  const double cos_d = std::max(std::abs(glm::dot(wo, d.axis)), kMinCosView);
  const double s_h = 1.0 / std::sqrt(d.lambda);
  SplitRow(w.axis, glm::normalize(across), 2.0 * cos_d * s_h, 2.0 * s_h, [&](const glm::dvec3& c, double l, double a) {
    Push(Sg{c, l, d.amplitude * a}, m_of(c), f, o.cosine, out);
  });
}

void LobesOf(const Lambertian& m, const ShadingFrame& f, const glm::dvec3&, const LobeOptions&,
             std::vector<Lobe>* out) {
  out->push_back({CosineSg(f.n), m.albedo / kPi, glm::dvec3(0), true});
}

// A sheen's light comes from every direction, strongest at grazing ones: one clamped cosine of
// its albedo for this view, E(wo)/π, so that under a constant light it reflects exactly E(wo).
void LobesOf(const Sheen& m, const ShadingFrame& f, const glm::dvec3& wo, const LobeOptions&, std::vector<Lobe>* out) {
  out->push_back({CosineSg(f.n), m.color * (SheenAlbedo(glm::dot(f.n, wo), m.roughness) / kPi), glm::dvec3(0), true});
}

void LobesOf(const Phong& m, const ShadingFrame& f, const glm::dvec3& wo, const LobeOptions& o,
             std::vector<Lobe>* out) {
  const Sg lobe{Reflect(wo, f.n), std::max(0.0, m.exponent), 1.0};
  Push(lobe, m.ks * ((m.exponent + 2.0) / (2.0 * kPi)), f, o.cosine, out);
}

void LobesOf(const BlinnPhong& m, const ShadingFrame& f, const glm::dvec3& wo, const LobeOptions& o,
             std::vector<Lobe>* out) {
  const glm::dvec3 ks = m.ks * ((m.exponent + 8.0) / (8.0 * kPi));
  PushWarped(
      Sg{f.n, std::max(0.0, m.exponent), 1.0}, [&](const glm::dvec3&) { return ks; }, f, wo, o, out);
}

void LobesOf(const Ward& m, const ShadingFrame& f, const glm::dvec3& wo, const LobeOptions& o, std::vector<Lobe>* out) {
  const double ax = std::max(m.alpha_x, 1e-3), ay = std::max(m.alpha_y, 1e-3);
  const double cos_o = glm::dot(f.n, wo);
  const auto m_of = [&](const glm::dvec3& wi) {
    const double cos_i = std::max(glm::dot(f.n, wi), kMinCosView);
    return m.rho_s / (4.0 * kPi * ax * ay * std::sqrt(cos_i * cos_o));
  };
  // In tan θ_h coordinates (u along t, v along b) D = exp(−u²/αx² − v²/αy²): Gaussians of
  // σ = α/√2, and an isotropic SG of λ has σ² = 1/λ near its axis.
  const double s_short = std::min(ax, ay) / std::sqrt(2.0), s_long = std::max(ax, ay) / std::sqrt(2.0);
  if (s_long - s_short < 1e-3 * s_short) {
    PushWarped(Sg{f.n, 1.0 / (s_short * s_short), 1.0}, m_of, f, wo, o, out);
    return;
  }
  // Anisotropic: split in half-vector space; each part is warped by eq. 4.10 alone (splitting
  // again would square the lobe count).
  LobeOptions iso = o;
  iso.warp = WarpMode::kIsotropic;
  SplitRow(f.n, ax >= ay ? f.t : f.b, s_short, s_long, [&](const glm::dvec3& c, double l, double a) {
    if (glm::dot(c, wo) <= 0) return;  // a half vector facing away from the viewer reflects nothing
    PushWarped(Sg{c, l, a}, m_of, f, wo, iso, out);
  });
}

// `principled`: CookTorrance::principled.
void PushCookTorrance(const glm::dvec3& f0, double alpha, Ndf ndf, bool principled, const ShadingFrame& f,
                      const glm::dvec3& wo, const LobeOptions& o, std::vector<Lobe>* out) {
  alpha = ClampAlpha(alpha);
  const double cos_o = glm::dot(f.n, wo);
  const auto m_of = [&](const glm::dvec3& wi) {
    const double cos_i = std::max(glm::dot(f.n, wi), kMinCosView);
    const glm::dvec3 h = glm::normalize(wi + wo);
    return FresnelOf(principled ? Fresnel::kPrincipled : Fresnel::kSchlick, f0, glm::dot(wi, h)) *
           (SmithG(ndf, alpha, cos_i, cos_o, principled) / (4.0 * cos_i * cos_o));
  };
  if (ndf == Ndf::kBeckmann) {
    PushWarped(Sg{f.n, NdfSgLambda(alpha), 1.0 / (kPi * alpha * alpha)}, m_of, f, wo, o, out);
    return;
  }
  // GGX: the peak SG warped as o says; the tail SG, wide and smooth, by eq. 4.10 alone (splitting
  // it too would double the glossy lobes and their cones, brdf.h).
  const GgxSgFit fit = GgxSg(alpha);
  PushWarped(Sg{f.n, fit.lambda[0], fit.amplitude[0]}, m_of, f, wo, o, out);
  if (fit.amplitude[1] <= 0) return;
  LobeOptions tail = o;
  tail.warp = WarpMode::kIsotropic;
  const std::size_t first = out->size();
  PushWarped(Sg{f.n, fit.lambda[1], fit.amplitude[1]}, m_of, f, wo, tail, out);
  const double share = GgxTailShare(fit);
  for (std::size_t i = first; i < out->size(); ++i) (*out)[i].tail_share = share;
}

void LobesOf(const CookTorrance& m, const ShadingFrame& f, const glm::dvec3& wo, const LobeOptions& o,
             std::vector<Lobe>* out) {
  PushCookTorrance(m.f0, m.alpha, m.ndf, m.principled, f, wo, o, out);
}

void LobesOf(const MetallicRoughness& m, const ShadingFrame& f, const glm::dvec3& wo, const LobeOptions& o,
             std::vector<Lobe>* out) {
  const MrParams p = FromMetallicRoughness(m);
  // f_d's retro-reflection at grazing views, FV r (1 + wi·wo), is linear in wi: the Lambertian
  // lobe carries it as (a0 + a1 wo·wi) with a1 = FV r, and a0 keeps the directional albedo.
  // With x = wi·wo, f_d π = (1 − FV/2) + r FV (1 + x) + FL B(x), B(x) = −(1 − FV/2)/2 +
  // r (1 − FV)(1 + x) + r² FV (1 + x)²: a0 + a1 x exactly, and FL B(x) as the grazing factor.
  const double mu = glm::dot(f.n, wo), r = p.roughness;
  const double fv = std::pow(1.0 - std::clamp(mu, 0.0, 1.0), 5.0);
  const double a1 = fv * r, a0 = 1.0 - 0.5 * fv + fv * r;
  const glm::dvec3 b(-0.5 * (1.0 - 0.5 * fv) + r * (1.0 - fv) + r * r * fv, r * (1.0 - fv) + 2.0 * r * r * fv,
                     r * r * fv);
  const glm::dvec3 diffuse = p.c_diff * (a0 / kPi);
  if (diffuse.x > 0 || diffuse.y > 0 || diffuse.z > 0)
    out->push_back({CosineSg(f.n), diffuse, (a1 / a0) * wo, true, b / a0, wo});
  PushCookTorrance(p.f0, p.alpha, Ndf::kGgx, true, f, wo, o, out);
}

}  // namespace

glm::dvec3 FresnelOf(Fresnel fresnel, const glm::dvec3& f0, double cos_theta) {
  double w;
  if (fresnel == Fresnel::kSchlick) {
    const double m = std::clamp(1.0 - cos_theta, 0.0, 1.0);
    const double m2 = m * m;
    w = m2 * m2 * m;
  } else {
    // Cycles' fresnel_dielectric_cos with η = 1.5: g = √(η² − 1 + c²).
    const double c = std::clamp(std::abs(cos_theta), 0.0, 1.0), g = std::sqrt(1.25 + c * c);
    const double a = (g - c) / (g + c), b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    w = std::max((0.5 * a * a * (1.0 + b * b) - 0.04) / 0.96, 0.0);
  }
  return f0 + (glm::dvec3(1.0) - f0) * w;
}

double PrincipledDiffuseFactor(double cos_i, double cos_o, double cos_io, double roughness) {
  const double fl = std::pow(std::clamp(1.0 - cos_i, 0.0, 1.0), 5.0);
  const double fv = std::pow(std::clamp(1.0 - cos_o, 0.0, 1.0), 5.0);
  const double rr = std::clamp(roughness, 0.0, 1.0) * (1.0 + cos_io);
  return (1.0 - 0.5 * fl) * (1.0 - 0.5 * fv) + rr * (fl + fv + fl * fv * (rr - 1.0));
}

// With x = wi·wo, μ = n·wo and the hemisphere's moments (1/π)∫ FL c = 1/21, (1/π)∫ FL c² = 1/84,
// (1/π)∫ FL c³ = 1/252, (1/π)∫ c wi = (2/3) n, (1/π)∫ FL c wi wiᵀ = n nᵀ/252 + (11/504)(I − n nᵀ):
//   (1/π)∫ (1 + x) c = 1 + 2μ/3,  (1/π)∫ (1 + x) FL c = 1/21 + μ/84,
//   (1/π)∫ (1 + x)² FL c = 1/21 + μ/42 + (11 − 9μ²)/504.
double PrincipledDiffuseAlbedo(double cos_o, double roughness) {
  const double mu = std::clamp(cos_o, 0.0, 1.0), r = std::clamp(roughness, 0.0, 1.0);
  const double fv = std::pow(1.0 - mu, 5.0);
  return (1.0 - 0.5 * fv) * (1.0 - 1.0 / 42.0) + fv * r * (1.0 + 2.0 * mu / 3.0) +
         r * (1.0 - fv) * (1.0 / 21.0 + mu / 84.0) +
         fv * r * r * (1.0 / 21.0 + mu / 42.0 + (11.0 - 9.0 * mu * mu) / 504.0);
}

ShadingFrame ShadingFrame::FromNormal(const glm::dvec3& n, const glm::dvec3& tangent_hint) {
  ShadingFrame f;
  f.n = glm::normalize(n);
  glm::dvec3 t = tangent_hint - glm::dot(tangent_hint, f.n) * f.n;
  if (glm::length(t) < 1e-6) {
    const glm::dvec3 other = std::abs(f.n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 0, 1);
    t = other - glm::dot(other, f.n) * f.n;
  }
  f.t = glm::normalize(t);
  f.b = glm::cross(f.n, f.t);
  return f;
}

double NdfSgLambda(double alpha) {
  alpha = ClampAlpha(alpha);
  // I(λ) = ∫₀¹ e^{λ(x−1)} x dx = 1/λ − (1 − e^{−λ})/λ² decreases from 1/2 (λ = 0) to 0; the
  // condition (2/α²) I(λ) = 1 is I(λ) = α²/2. Bisection: robust for every α in [kMinAlpha, 1].
  const auto integral = [](double l) {
    if (l < 1e-3) return 0.5 - l / 6.0 + l * l / 24.0;
    return 1.0 / l + std::expm1(-l) / (l * l);
  };
  const double target = 0.5 * alpha * alpha;
  double lo = 0, hi = 2.0 / (alpha * alpha) + 1.0;
  if (integral(lo) <= target) return 0;
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    (integral(mid) > target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

GgxSgFit GgxSg(double alpha) {
  alpha = ClampAlpha(alpha);
  const double l0 = NdfSgLambda(alpha);
  // The fit is GGX's small-α shape; towards α = 1, where GGX flattens to 1/π and one SG of
  // NdfSgLambda is exact, it fades (linearly in α) into that SG.
  const double t = std::clamp((kGgxSgFadeEnd - alpha) / (kGgxSgFadeEnd - kGgxSgFadeBegin), 0.0, 1.0);
  const double scale[2] = {1.0 + t * (kGgxSgLambdaScale[0] - 1.0), kGgxSgLambdaScale[1]};
  const double weight[2] = {1.0 - t * kGgxSgWeight[1], t * kGgxSgWeight[1]};
  const auto integral = [](double l) {  // ∫₀¹ e^{λ(x−1)} x dx, as in NdfSgLambda
    if (l < 1e-3) return 0.5 - l / 6.0 + l * l / 24.0;
    return 1.0 / l + std::expm1(-l) / (l * l);
  };
  double sum = 0;
  for (int i = 0; i < 2; ++i) sum += weight[i] * integral(scale[i] * l0);
  const double c = alpha * alpha / (2.0 * sum);  // ∫ D (n·h) = 1
  GgxSgFit fit;
  for (int i = 0; i < 2; ++i) {
    fit.lambda[i] = scale[i] * l0;
    fit.amplitude[i] = c * weight[i] / (kPi * alpha * alpha);
  }
  return fit;
}

double GgxTailShare(const GgxSgFit& fit) {
  if (!(fit.amplitude[1] > 0)) return 0.0;
  double part[2];
  for (int k = 0; k < 2; ++k) {
    const double l = fit.lambda[k];
    part[k] = fit.amplitude[k] * (l < 1e-6 ? 2.0 : -std::expm1(-2.0 * l) / l);
  }
  return part[1] / (part[0] + part[1]);
}

Sg WarpToIncident(const Sg& half_vector_lobe, const glm::dvec3& wo) {
  const double d = glm::dot(wo, half_vector_lobe.axis);
  Sg w;
  w.axis = glm::normalize(Reflect(wo, half_vector_lobe.axis));
  // The Jacobian |dh/dwi| = 1/(4 |wo·h|) at the axis; clamped so a grazing view stays finite.
  w.lambda = half_vector_lobe.lambda / (4.0 * std::max(std::abs(d), kMinCosView));
  w.amplitude = half_vector_lobe.amplitude;
  return w;
}

Sg CosineSg(const glm::dvec3& n) { return Sg{n, kCosineSgLambda, kCosineSgAmplitude}; }

glm::dvec3 Evaluate(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wi, const glm::dvec3& wo) {
  if (glm::dot(frame.n, wi) <= 0) return glm::dvec3(0);
  const glm::dvec3 v = BendView(frame, wo);
  return std::visit([&](const auto& m) { return Analytic(m, frame, wi, v); }, brdf);
}

void AppendLobes(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wo, std::vector<Lobe>* lobes,
                 const LobeOptions& options) {
  const glm::dvec3 v = BendView(frame, wo);
  std::visit([&](const auto& m) { LobesOf(m, frame, v, options, lobes); }, brdf);
}

std::vector<Lobe> Lobes(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wo, const LobeOptions& options) {
  std::vector<Lobe> lobes;
  AppendLobes(brdf, frame, wo, &lobes, options);
  return lobes;
}

namespace {

// e^{−x} I0(x) for x ≥ 0 (Abramowitz & Stegun 9.8.1–9.8.2, relative error < 2·10⁻⁷).
double ScaledBesselI0(double x) {
  if (x <= 3.75) {
    const double t = (x / 3.75) * (x / 3.75);
    return std::exp(-x) *
           (1 +
            t * (3.5156229 + t * (3.0899424 + t * (1.2067492 + t * (0.2659732 + t * (0.0360768 + t * 0.0045813))))));
  }
  const double t = 3.75 / x;
  return (0.39894228 +
          t * (0.01328592 +
               t * (0.00225319 +
                    t * (-0.00157565 +
                         t * (0.00916281 +
                              t * (-0.02057706 + t * (0.02635537 + t * (-0.01647633 + t * 0.00392377)))))))) /
         std::sqrt(x);
}

// ∫ G max(0, n·w) / ∫ G by quadrature. With n the pole (w at polar angle α, azimuth φ from the
// plane of n and c), ∫ e^{λ(z cos α + s sin α cos φ − 1)} dφ = 2π e^{λ(z cos α − 1)} I0(λ s sin α),
// s = sin θ, leaving ∫₀^{π/2} … cos α sin α dα: a midpoint rule of 128 steps (λ ≤ 64, so the
// SG is at least 1/8 rad wide).
double ClampedCosineMeanByQuadrature(double z, double lambda, bool grazing) {
  const double s = std::sqrt(std::max(0.0, 1 - z * z));
  constexpr int kSteps = 128;
  double sum = 0;
  for (int i = 0; i < kSteps; ++i) {
    const double a = (i + 0.5) * (kPi / 2) / kSteps;
    const double x = lambda * s * std::sin(a);
    const double fl = grazing ? std::pow(1 - std::cos(a), 5.0) : 1.0;
    sum += std::exp(lambda * (z * std::cos(a) - 1) + x) * ScaledBesselI0(x) * std::cos(a) * std::sin(a) * fl;
  }
  sum *= 2 * kPi * (kPi / 2) / kSteps;
  const double integral = lambda < 1e-9 ? 4 * kPi : 2 * kPi * -std::expm1(-2 * lambda) / lambda;
  return sum / integral;
}

double RowLambda(int row) {
  const double q = double(row) / (kClampedCosineRows - 1) *
                   (kClampedCosineLambdaMax / (kClampedCosineLambdaMax + kClampedCosineKappa));
  return kClampedCosineKappa * q / (1 - q);
}

}  // namespace

const std::vector<double>& ClampedCosineTable() {
  static const std::vector<double> table = [] {
    const std::size_t block = static_cast<std::size_t>(kClampedCosineRows) * kClampedCosineZ;
    std::vector<double> t(2 * block);
    for (int r = 0; r < kClampedCosineRows; ++r)
      for (int i = 0; i < kClampedCosineZ; ++i) {
        const std::size_t k = static_cast<std::size_t>(r) * kClampedCosineZ + i;
        const double z = -1.0 + 2.0 * i / (kClampedCosineZ - 1);
        t[k] = ClampedCosineMeanByQuadrature(z, RowLambda(r), false);
        t[block + k] = ClampedCosineMeanByQuadrature(z, RowLambda(r), true);
      }
    return t;
  }();
  return table;
}

namespace {

// The two columns of ClampedCosineTable: FL = 0 (the mean) or 1 (the grazing mean).
double ClampedCosineLookup(double z, double lambda, int column) {
  z = std::clamp(z, -1.0, 1.0);
  lambda = std::max(lambda, 0.0);
  if (lambda >= kClampedCosineLambdaMax) {
    // Near the horizon X = n·w ~ N(z, 1/λ): E[X⁺] = z Φ + φ/√λ.
    const double k = std::sqrt(lambda), x = z * k;
    const double cdf = 0.5 * std::erfc(-x / std::sqrt(2.0)), pdf = std::exp(-0.5 * x * x) / std::sqrt(2 * kPi);
    if (column == 0) return SgMeanCosine(lambda) * (z * cdf + pdf / k);
    // FL = (1 − X)⁵ against X⁺ needs X's spread along n: X ~ N(z (coth λ − 1/λ), (1 − z²)/λ +
    // 1/λ²), and Σ_j C(5, j) (−1)^j E[X⁺ X^j] by the truncated moments M_j = E[X^j; X > 0]:
    // M_0 = Φ, M_1 = m Φ + σ φ, M_j = m M_{j−1} + (j − 1) σ² M_{j−2}. Within 2 % where it matters.
    const double m = z * SgMeanCosine(lambda), s2 = (1 - z * z) / lambda + 1 / (lambda * lambda), s = std::sqrt(s2);
    const double xs = m / s;
    const double phi = std::exp(-0.5 * xs * xs) / std::sqrt(2 * kPi);
    double moments[7];
    moments[0] = 0.5 * std::erfc(-xs / std::sqrt(2.0));
    moments[1] = m * moments[0] + s * phi;
    for (int j = 2; j < 7; ++j) moments[j] = m * moments[j - 1] + (j - 1) * s2 * moments[j - 2];
    constexpr double kBinomial[6] = {1, -5, 10, -10, 5, -1};
    double fl = 0;
    for (int j = 0; j < 6; ++j) fl += kBinomial[j] * moments[j + 1];
    return std::max(fl, 0.0);
  }
  const double* t =
      ClampedCosineTable().data() + static_cast<std::size_t>(column) * kClampedCosineRows * kClampedCosineZ;
  const double row = lambda / (lambda + kClampedCosineKappa) /
                     (kClampedCosineLambdaMax / (kClampedCosineLambdaMax + kClampedCosineKappa)) *
                     (kClampedCosineRows - 1);
  const int r = std::min(static_cast<int>(row), kClampedCosineRows - 2);
  const double col = (z + 1) / 2 * (kClampedCosineZ - 1);
  const int c = std::clamp(static_cast<int>(col), 0, kClampedCosineZ - 2);
  const double fr = row - r, fc = col - c;
  const auto at = [&](int rr, int cc) { return t[static_cast<std::size_t>(rr) * kClampedCosineZ + cc]; };
  return (1 - fr) * ((1 - fc) * at(r, c) + fc * at(r, c + 1)) + fr * ((1 - fc) * at(r + 1, c) + fc * at(r + 1, c + 1));
}

}  // namespace

double ClampedCosineMean(double z, double lambda) { return ClampedCosineLookup(z, lambda, 0); }
double ClampedCosineGrazingMean(double z, double lambda) { return ClampedCosineLookup(z, lambda, 1); }

double ClampedCosineLobeIntegral(const Lobe& lobe, const Sg& g, const Sg& product) {
  const double z = glm::dot(lobe.sg.axis, g.axis);
  const double integral = lighting::Integral(g);
  double i = ClampedCosineMean(z, g.lambda) * LinearFactor(lobe.linear, product);
  if (lobe.grazing != glm::dvec3(0)) {
    const double x = glm::dot(lobe.view, product.axis) * SgMeanCosine(product.lambda);
    i += ClampedCosineGrazingMean(z, g.lambda) * (lobe.grazing.x + x * (lobe.grazing.y + x * lobe.grazing.z));
  }
  return i * integral;
}

double ClampedCosineIntegral(const glm::dvec3& n, const Sg& g) {
  return ClampedCosineMean(glm::dot(n, g.axis), g.lambda) * lighting::Integral(g);
}

double SgMeanCosine(double lambda) { return lambda < 1e-3 ? lambda / 3.0 : 1.0 / std::tanh(lambda) - 1.0 / lambda; }

double LinearFactor(const glm::dvec3& linear, const Sg& product) {
  if (linear == glm::dvec3(0)) return 1.0;
  return 1.0 + glm::dot(linear, product.axis) * SgMeanCosine(product.lambda);
}

glm::dvec3 ShadeUnderSgLight(std::span<const Lobe> lobes, const lighting::RgbSg& light, const Sg* visibility) {
  const Sg l{light.axis, light.lambda, 1.0};
  glm::dvec3 sum(0);
  const Sg lit = visibility ? lighting::Product(l, *visibility) : l;
  for (const Lobe& lobe : lobes) {
    Sg product = lighting::Product(lobe.sg, l);
    if (visibility) product = lighting::Product(product, *visibility);
    if (lobe.clamped_cosine) {
      sum += lobe.weight * ClampedCosineLobeIntegral(lobe, lit, product);
      continue;
    }
    const double i =
        visibility ? lighting::IntegralOfProduct(lobe.sg, l, *visibility) : lighting::IntegralOfProduct(lobe.sg, l);
    sum += lobe.weight * (i * LinearFactor(lobe.linear, product));
  }
  return sum * glm::dvec3(light.amplitude);
}

glm::dvec3 GgxLobeResidual(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wi, const glm::dvec3& wo,
                           std::span<const Lobe> lobes) {
  const glm::dvec3 v = BendView(frame, wo);
  const auto* mr = std::get_if<MetallicRoughness>(&brdf);
  const auto* ct = std::get_if<CookTorrance>(&brdf);
  if (!mr && !(ct && ct->ndf == Ndf::kGgx)) return glm::dvec3(0);
  const CookTorrance ggx =
      mr ? CookTorrance{FromMetallicRoughness(*mr).f0, FromMetallicRoughness(*mr).alpha, Ndf::kGgx, true} : *ct;
  const double cos_i = glm::dot(frame.n, wi);
  glm::dvec3 exact = cos_i > 0 ? Analytic(ggx, frame, wi, v) * cos_i : glm::dvec3(0);
  for (const Lobe& lobe : lobes)
    if (!lobe.clamped_cosine)
      exact -= lobe.weight * (lighting::Evaluate(lobe.sg, wi) * (1.0 + glm::dot(lobe.linear, wi)));
  return exact;
}

glm::dvec3 GgxResidualUnderSgLight(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wo,
                                   std::span<const Lobe> lobes, const Sg& light) {
  const auto* ct = std::get_if<CookTorrance>(&brdf);
  if (!std::holds_alternative<MetallicRoughness>(brdf) && !(ct && ct->ndf == Ndf::kGgx)) return glm::dvec3(0);
  const glm::dvec3 c = light.axis;
  const glm::dvec3 helper = std::abs(c.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  const glm::dvec3 e1 = glm::normalize(glm::cross(c, helper)), e2 = glm::cross(c, e1);
  const double r = 2.0 / std::sqrt(std::max(light.lambda, 1e-6));
  glm::dvec3 sum = 0.5 * GgxLobeResidual(brdf, frame, c, wo, lobes);
  for (int k = 0; k < 6; ++k) {
    const double a = k * kPi / 3;
    sum +=
        GgxLobeResidual(brdf, frame, glm::normalize(c + r * (std::cos(a) * e1 + std::sin(a) * e2)), wo, lobes) / 12.0;
  }
  return sum * lighting::Integral(light);
}

glm::dvec3 ShadeUnderSgLights(std::span<const Lobe> lobes, std::span<const lighting::RgbSg> lights) {
  glm::dvec3 sum(0);
  for (const auto& light : lights) sum += ShadeUnderSgLight(lobes, light);
  return sum;
}

namespace {

std::string FormatBound(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}

void CheckIn(const char* model, const char* name, double x, double lo, double hi, bool open_below = false) {
  const bool above = open_below ? x > lo : x >= lo;
  if (!(above && x <= hi))
    throw Error(std::string("BRDF ") + model, std::string(name) + " must be in " + (open_below ? "(" : "[") +
                                                  FormatBound(lo) + ", " + FormatBound(hi) + "], got " +
                                                  FormatBound(x));
}

void CheckColour(const char* model, const char* name, const glm::dvec3& c) {
  for (int i = 0; i < 3; ++i) CheckIn(model, name, c[i], 0, 1);
}

}  // namespace

void CheckBrdf(const Brdf& brdf) {
  if (const auto* l = std::get_if<Lambertian>(&brdf)) {
    CheckColour("lambert", "albedo", l->albedo);
  } else if (const auto* p = std::get_if<Phong>(&brdf)) {
    CheckColour("phong", "ks", p->ks);
    CheckIn("phong", "exponent", p->exponent, 0, 1e5);
  } else if (const auto* b = std::get_if<BlinnPhong>(&brdf)) {
    CheckColour("blinn", "ks", b->ks);
    CheckIn("blinn", "exponent", b->exponent, 0, 1e5);
  } else if (const auto* w = std::get_if<Ward>(&brdf)) {
    CheckColour("ward", "rho_s", w->rho_s);
    CheckIn("ward", "alpha_x", w->alpha_x, 0, 1, true);
    CheckIn("ward", "alpha_y", w->alpha_y, 0, 1, true);
  } else if (const auto* c = std::get_if<CookTorrance>(&brdf)) {
    CheckColour("ct", "f0", c->f0);
    CheckIn("ct", "alpha", c->alpha, 0, 1, true);
  } else if (const auto* m = std::get_if<MetallicRoughness>(&brdf)) {
    CheckColour("mr", "base colour", m->base_color);
    CheckIn("mr", "metallic", m->metallic, 0, 1);
    CheckIn("mr", "roughness", m->roughness, 0, 1);
  } else if (const auto* s = std::get_if<Sheen>(&brdf)) {
    CheckColour("sheen", "colour", s->color);
    CheckIn("sheen", "roughness", s->roughness, 0, 1);
  }
}

const std::vector<double>& SheenAlbedoTable() {
  // Midpoint quadrature over the hemisphere in (n·wi, φ), φ over [0, π] by symmetry, n·wi in
  // squared steps (the nodes crowd at the horizon, where a smooth sheen's light comes from). Per
  // view and point, log sin θ_h and the rest of the integrand once; per roughness one exp.
  static const std::vector<double> table = [] {
    constexpr int kCos = 256, kPhi = 128;
    constexpr int n = kSheenTableNodes;
    std::vector<double> values(static_cast<std::size_t>(n) * n, 0.0);
    std::vector<double> inv_alpha(n);
    for (int j = 0; j < n; ++j) {
      const double r = static_cast<double>(j) / (n - 1);
      inv_alpha[static_cast<std::size_t>(j)] = 1.0 / std::max(r * r, kMinSheenAlpha);
    }
    for (int i = 0; i < n; ++i) {
      const double mu_o = std::max(static_cast<double>(i) / (n - 1), kMinCosView);
      const double s_o = std::sqrt(1.0 - mu_o * mu_o);
      for (int a = 0; a < kCos; ++a) {
        const double u = (a + 0.5) / kCos, mu_i = u * u, s_i = std::sqrt(1.0 - mu_i * mu_i);
        // d(n·wi) = 2u du; the visibility and the cosine; the φ step (2π over the half range).
        const double w = (2.0 * u / kCos) * mu_i / (4.0 * (mu_i + mu_o - mu_i * mu_o)) * (2.0 * kPi / kPhi);
        for (int b = 0; b < kPhi; ++b) {
          const double cos_phi = std::cos(kPi * (b + 0.5) / kPhi);
          const double hz = mu_i + mu_o, h2 = 2.0 + 2.0 * (mu_i * mu_o + s_i * s_o * cos_phi);
          const double sin2 = std::max(0.0, 1.0 - hz * hz / h2);
          if (!(sin2 > 0)) continue;
          const double log_sin = 0.5 * std::log(sin2);
          for (int j = 0; j < n; ++j) {
            const double k = inv_alpha[static_cast<std::size_t>(j)];
            values[static_cast<std::size_t>(j) * n + static_cast<std::size_t>(i)] +=
                w * (2.0 + k) / (2.0 * kPi) * std::exp(k * log_sin);
          }
        }
      }
    }
    return values;
  }();
  return table;
}

double SheenAlbedo(double cos_view, double roughness) {
  const std::vector<double>& t = SheenAlbedoTable();
  const double x = std::clamp(cos_view, 0.0, 1.0) * (kSheenTableNodes - 1);
  const double y = std::clamp(roughness, 0.0, 1.0) * (kSheenTableNodes - 1);
  const int i = std::min(static_cast<int>(x), kSheenTableNodes - 2),
            j = std::min(static_cast<int>(y), kSheenTableNodes - 2);
  const double fx = x - i, fy = y - j;
  const auto at = [&](int c, int r) {
    return t[static_cast<std::size_t>(r) * kSheenTableNodes + static_cast<std::size_t>(c)];
  };
  return (1 - fy) * ((1 - fx) * at(i, j) + fx * at(i + 1, j)) + fy * ((1 - fx) * at(i, j + 1) + fx * at(i + 1, j + 1));
}

}  // namespace odvr::material
