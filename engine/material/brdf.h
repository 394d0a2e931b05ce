#pragma once
// BRDF models and their spherical-Gaussian lobes (seed §4.2, DESIGN.md §5).
//
// Conventions
// - Directions are unit vectors pointing away from the surface: `wi` towards the light, `wo`
//   towards the viewer; `n` is the unit shading normal. f is in sr⁻¹, per RGB channel.
// - Reflected radiance L_o(wo) = ∫ f(wi, wo) L(wi) max(0, n·wi) dwi. The lobes below approximate
//   the whole integrand factor f(wi, wo) · max(0, n·wi) as a function of wi for one wo:
//     f(wi, wo) max(0, n·wi) ≈ Σ_k weight_k · G(wi; c_k, λ_k, μ_k),
//   so shading under SG lighting (and SG visibility) is a sum of closed-form SG integrals.
// - A view at or below the horizon (n·wo < kMinCosView) is treated as grazing at kMinCosView,
//   in the analytic BRDFs and the lobes alike, so silhouettes with bent shading normals never go
//   black or divide by zero.
//
// Approximations (each measured against quadrature of the analytic BRDF in brdf_test.cpp)
// - Microfacet BRDFs are M(wi, wo) D(h) (eq. 4.8). D is one SG in half-vector space around n (a
//   row of SGs for anisotropic Ward), warped to incident-direction space by eq. 4.10 after Wang et
//   al. 2009: axis c' = 2(wo·c)c − wo (the view reflected about the lobe axis c),
//   λ' = λ / (4 |wo·c|), μ' = μ. M (Fresnel, shadowing-masking, the 1/(n·wi n·wo) factors) is
//   evaluated at the warped axis wi = c', where it is smooth compared with D.
// - The cosine max(0, n·wi): for lobes it is, by default, folded into the weight at the lobe axis
//   (CosineTerm::kAtLobeAxis); CosineTerm::kAsSg multiplies the lobe by the clamped-cosine SG
//   instead. The Lambertian lobe is the clamped cosine itself (Lobe::clamped_cosine): against an
//   SG light (or the SG product of a light and a visibility SG) it integrates exactly, through
//   ClampedCosineMean, a table of the 2D function ∫ G max(0, n·w) / ∫ G. Its SG stand-in, λ =
//   2.133, μ = 1.170 (Wang et al. 2009's fit of max(0, cos θ)), only places the lobe for what
//   needs an SG: the visibility cones and their weights, the overlap bins, the linear factor's mean
//   direction. That fit alone would be 17 % high at the normal, 19 % low at 60°, 8 % high over
//   the sphere, and leak 1.6–14 % of the zenith response below the horizon.
// - Phong's lobe already lives around the reflected direction r = 2(n·wo)n − wo: cosⁿ(r·wi) ≈
//   SG(r, λ = n) with no warp. Blinn-Phong: (n·h)^s ≈ SG(h; n, λ = s), then the warp.
// - Ward: exp(−tan²θ_h/α²) ≈ SG(h; n, λ = 2/α²) (equal curvature at the peak). Anisotropic:
//   the Gaussian along the wider tangent is written as a convolution of the narrow isotropic SG
//   with a 1D Gaussian and sampled with a trapezoid rule (ripple < 0.5 %): 2K+1 isotropic SGs of
//   λ = 2/α_min² on a line along the wide tangent (at most kMaxAnisotropicLobes).
// - Cook-Torrance: D (GGX or Beckmann, α) ≈ SG(h; n, λ(α), μ = 1/(π α²)), with λ(α) solving
//   2π μ ∫₀¹ e^{λ(x−1)} x dx = 1: the SG has D's peak value and D's normalisation over the
//   hemisphere. λ(α) → 2/α² − 1 as α → 0, and λ(1) = 0 (GGX at α = 1 *is* the constant 1/π).
//   That one SG suits Beckmann (a Gaussian in tan θ_h); GGX's peak is sharper and its tails far
//   heavier (1/(1 + tan²θ_h/α²)² against a Gaussian), so GGX is two SGs around n (GgxSg): a
//   narrow one holding the peak and a wide one, with 11 % of the peak and 45 % of the energy, for
//   the tail. The narrow one is warped as LobeOptions says; the wide one always by eq. 4.10 (its
//   anisotropy matters less, and splitting it would double the glossy lobes and their cones).
//   F is Schlick's, G the height-correlated Smith term 1/(1 + Λ(wi) + Λ(wo)) of the chosen NDF
//   (CookTorrance::principled: the Principled BSDF's F and separable G, as metallic-roughness).
// - glTF metallic-roughness, as Blender's glTF importer makes it: a Principled BSDF (v1, Blender
//   3.4, specular 0.5), the material our Cycles references and street_a's were rendered with.
//   α = roughness² clamped to ≥ kMinAlpha, F0 = mix(0.04, base, metallic), c_diff = base
//   (1 − metallic); f = c_diff f_d + D F G/(4 (n·wi)(n·wo)) with GGX and the Principled BSDF's
//   specular as Cycles 3.x computes it (CookTorrance::principled): F(wi·h) is the dielectric
//   Fresnel of IOR 1.5 remapped from 0.04 to F0 (Fresnel::kPrincipled), where glTF's Schlick has
//   (1 − cos)⁵ (a dielectric reflects 1.2–1.3× Schlick's at 45–65°), and G the separable Smith
//   G1(wi) G1(wo), not the height-correlated one; against the Cycles references every paint's
//   error fell with them.
//   f_d is Cycles' principled diffuse (Burley 2015): (1/π)[(1 − FL/2)(1 − FV/2) + RR (FL + FV +
//   FL FV (RR − 1))], FL = (1 − n·wi)⁵, FV = (1 − n·wo)⁵, RR = roughness (1 + wi·wo): the
//   retro-reflection of rough surfaces brightens grazing views and light from behind the viewer.
//   The Principled BSDF adds its specular layer on top of the diffuse one, without the glTF
//   spec's (1 − F) on the diffuse: against Cycles a Lambertian (1 − F) diffuse read the diffuse
//   paints clearly dark. The lobes: the clamped
//   cosine with f_d's terms constant in FL as its weight and exact linear factor (Lobe::linear:
//   the retro-reflection at grazing views FV r (1 + wi·wo)), the FL terms (light at grazing
//   incidence) as its grazing factor (Lobe::grazing, integrated through ClampedCosineGrazingMean,
//   wi·wo taken at the mean direction), plus the GGX lobe.
//
// What that costs (brdf_test.cpp prints the table; SG light λ 10–1000, views 0–75°, error against
// quadrature): with a light aimed at the mirror direction 0.03 % (Phong n = 10⁴) to ~40 % (GGX
// α = 0.3 and the glTF paint, ~50 % with one SG for D); with the light 25° off it, up to
// ~100 % for glossy lobes, because eq. 4.10's isotropic lobe is too narrow in the plane of
// incidence — WarpMode::kAnisotropicSplit cuts those to ~30 %. Lambertian: ≤ 0.3 % (the table's
// interpolation). At grazing views (85–89°) the cosine at the axis goes to 0 and the errors of
// the glossy lobes are O(1).
#include <glm/vec3.hpp>
#include <span>
#include <variant>
#include <vector>

#include "engine/lighting/sg.h"
#include "engine/lighting/sg_lighting.h"

namespace odvr::material {

inline constexpr double kMinCosView = 1e-3;
// The mirror limit: λ ≈ 2/α² = 5·10⁵ in half-vector space. Low enough to leave a car's glass and
// headlamps (α below 0.01) their own sharpness: a floor of 0.01 widened them and raised the car's
// error against Cycles.
inline constexpr double kMinAlpha = 0.002;
inline constexpr int kMaxAnisotropicLobes = 15;
// GGX's two-SG fit (GgxSg): for small α, D π α² = 1/(1 + u²)² in u = θ_h/α, fitted by
// Σ_k w_k exp(−s_k u²) with s_k = kGgxSgLambdaScale[k] (the scale of NdfSgLambda ≈ 2/α²), the
// peak kept (Σ w_k = 1) and the normalisation (Σ w_k/s_k = 1): s and w chosen to minimise the worst
// relative error of D blurred by Gaussian lights of σ 0.2–4 α, at the peak and 1–3 σ off it:
// 6.4 % against one SG's 39 %. The narrow SG holds the peak, the wide one GGX's heavy tail.
inline constexpr double kGgxSgLambdaScale[2] = {1.625, 0.25};
inline constexpr double kGgxSgWeight[2] = {0.886364, 0.113636};
// Beyond small α GGX's shape departs from the fit's (1 at α = 1 is the constant 1/π): brdf_test's
// GGX α = 0.3 and 0.7 were worse with the full fit than with one SG at 0.7.
inline constexpr double kGgxSgFadeBegin = 0.3;
inline constexpr double kGgxSgFadeEnd = 0.7;
// Wang et al. 2009's single-SG fit of the clamped cosine max(0, n·w).
inline constexpr double kCosineSgLambda = 2.133;
inline constexpr double kCosineSgAmplitude = 1.170;
// ClampedCosineMean's table: kClampedCosineZ values of z = n·c on [−1, 1] (uniform) per row,
// kClampedCosineRows rows of λ on [0, kClampedCosineLambdaMax] uniform in λ/(λ + κ), κ =
// kClampedCosineKappa (dense at small λ, where the mean changes fastest). Measured against
// quadrature: ≤ 0.3 % relative where the mean is over 5 % of its peak, ≤ 10⁻³ absolute.
inline constexpr int kClampedCosineZ = 129;
inline constexpr int kClampedCosineRows = 33;
inline constexpr double kClampedCosineLambdaMax = 64;
inline constexpr double kClampedCosineKappa = 8;

// The surface frame: n the normal; t, b the tangent and bitangent (only anisotropic Ward uses
// them). Right-handed and orthonormal: b = n × t.
struct ShadingFrame {
  glm::dvec3 n{0, 1, 0};
  glm::dvec3 t{1, 0, 0};
  glm::dvec3 b{0, 0, -1};
  // A frame around `n` with t as close to `tangent_hint` as orthogonality allows.
  static ShadingFrame FromNormal(const glm::dvec3& n, const glm::dvec3& tangent_hint = {1, 0, 0});
};

struct Lambertian {
  glm::dvec3 albedo{0.8};  // ρ ∈ [0, 1]: f = ρ/π
};

// f = ks (n+2)/(2π) max(0, r·wi)^n, r the mirror of wo: energy-normalised Phong.
struct Phong {
  glm::dvec3 ks{1};
  double exponent = 50;
};

// f = ks (s+8)/(8π) (n·h)^s, the usual approximately energy-normalised Blinn-Phong.
struct BlinnPhong {
  glm::dvec3 ks{1};
  double exponent = 50;
};

// f = ρs / (4π αx αy √(cosθi cosθo)) exp(−tan²θh (cos²φh/αx² + sin²φh/αy²)); φh measured from
// the frame's t. αx = αy is the isotropic Ward.
struct Ward {
  glm::dvec3 rho_s{0.5};
  double alpha_x = 0.2;
  double alpha_y = 0.2;
};

enum class Ndf { kGgx, kBeckmann };

// F(cos) = f0 + (1 − f0) w(cos): Schlick's w = (1 − cos)⁵, or Blender's Principled BSDF (v1):
// w = (F_d(cos) − F_d(1)) / (1 − F_d(1)), F_d the unpolarized Fresnel reflectance of a dielectric
// of IOR 1.5 (F_d(1) = 0.04), which the Principled BSDF's specular 0.5 gives.
enum class Fresnel { kSchlick, kPrincipled };
glm::dvec3 FresnelOf(Fresnel fresnel, const glm::dvec3& f0, double cos_theta);

// f = D(h) F(wi·h) G(wi, wo) / (4 (n·wi)(n·wo)).
struct CookTorrance {
  glm::dvec3 f0{0.04};  // Fresnel reflectance at normal incidence
  double alpha = 0.2;   // GGX α or Beckmann m
  Ndf ndf = Ndf::kGgx;
  // Schlick's F and the height-correlated Smith G, or (true) the Principled BSDF v1's specular in
  // Cycles 3.x: FresnelOf(kPrincipled) and the separable G1(wi) G1(wo).
  bool principled = false;
};

// glTF 2.0 metallic-roughness, already sampled (base colour linear, not sRGB).
struct MetallicRoughness {
  glm::dvec3 base_color{0.8};
  double metallic = 0;
  double roughness = 0.5;  // perceptual
};

// glTF's KHR_materials_sheen, the layer a fabric adds at grazing angles: the Charlie sheen
// (Estevez & Kulla 2017), D(h) = (2 + 1/α) sin(θ_h)^(1/α) / 2π with α = roughness² (at least
// kMinSheenAlpha), and Neubelt's visibility V = 1 / (4 (n·wi + n·wo − (n·wi)(n·wo))):
// f = color D V. The renderer adds it to the glTF base layer, as Blender's glTF importer adds its
// Velvet, without the extension's albedo scaling of the base (1 − max(color) E(wo)).
struct Sheen {
  glm::dvec3 color{0};
  double roughness = 0.5;  // perceptual
};
inline constexpr double kMinSheenAlpha = 0.07 * 0.07;

// E(wo) = ∫ f(wi, wo) (n·wi) dwi / color of a sheen, for n·wo = cos_view and its roughness: from
// a table of 33 × 33 nodes over cos_view, roughness ∈ [0, 1] (a 256² quadrature each, made once),
// interpolated bilinearly (SheenAlbedoTable gives it as the shaders read it).
double SheenAlbedo(double cos_view, double roughness);
inline constexpr int kSheenTableNodes = 33;
// Row-major by roughness, then cos_view: kSheenTableNodes² values.
const std::vector<double>& SheenAlbedoTable();

using Brdf = std::variant<Lambertian, Phong, BlinnPhong, Ward, CookTorrance, MetallicRoughness, Sheen>;

// The parameters' ranges, one place for every caller: colours (albedo, ks, rho_s, f0, base
// colour), metallic and roughness in [0, 1]; Phong and Blinn-Phong exponents in [0, 10⁵] (past
// that the lobe is narrower than any SG level resolves); Ward's and Cook-Torrance's α in (0, 1]
// (α = 0 divides by zero). Throws odvr::Error naming the model and the value out of range; a
// NaN is out of every range.
void CheckBrdf(const Brdf& brdf);

// One term of the lobe sum: weight ⊙ G(wi; sg) (1 + linear·wi). The linear factor's integral
// against an SG light is exact: ∫ P (1 + ℓ·wi) = ∫P (1 + ℓ·c_P SgMeanCosine(λ_P)) for the product
// P of lobe and light (axis c_P, λ_P), since an SG's mean direction is c (coth λ − 1/λ).
// A clamped-cosine lobe (the diffuse ones) is instead, with n = sg.axis and x = view·wi,
//   weight ⊙ max(0, n·wi) [1 + linear·wi + (1 − n·wi)⁵ (grazing₀ + grazing₁ x + grazing₂ x²)],
// integrated by ClampedCosineLobeIntegral; `sg` is then CosineSg(n), its SG stand-in.
struct Lobe {
  lighting::Sg sg;
  glm::dvec3 weight{1};
  glm::dvec3 linear{0};
  bool clamped_cosine = false;
  glm::dvec3 grazing{0};  // Burley's FL terms (MetallicRoughness), relative to weight
  glm::dvec3 view{0};
  // GGX's tail SG (GgxSg): its share of D (GgxTailShare); 0 for every other lobe. A renderer
  // lights a tail only with the lighting levels whose detail it shows at that share
  // (lighting::OverlapBins::MaxLevel), the finer levels' energy moved onto the deepest of them.
  double tail_share = 0;
};

enum class CosineTerm { kAtLobeAxis, kAsSg };

// kIsotropic is eq. 4.10: one SG per half-vector SG, λ' = λ/(4|wo·c|). The true warped lobe is
// anisotropic: in the plane of incidence h turns by half the angle wi turns (σ_in = 2σ_h), across
// it by 1/(2cosθ_d) of it (σ_out = 2 cosθ_d σ_h, θ_d the angle between wo and c); eq. 4.10 gives
// both the geometric mean. kAnisotropicSplit writes that anisotropic lobe as a row of isotropic
// SGs of σ_out along the plane of incidence (the same 1D split as anisotropic Ward, at most
// kMaxAnisotropicLobes), each with M and the cosine at its own axis: more SGs, much less error
// at oblique and grazing views.
enum class WarpMode { kIsotropic, kAnisotropicSplit };

struct LobeOptions {
  CosineTerm cosine = CosineTerm::kAtLobeAxis;
  WarpMode warp = WarpMode::kIsotropic;
};

// The analytic BRDF f(wi, wo); 0 for wi below the horizon.
glm::dvec3 Evaluate(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wi, const glm::dvec3& wo);

// Appends the SG lobes of f(·, wo) · max(0, n·wi) to `lobes` (which it does not clear, so
// several materials can share one list). Lobes with zero weight are left out.
void AppendLobes(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wo, std::vector<Lobe>* lobes,
                 const LobeOptions& options = {});
std::vector<Lobe> Lobes(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wo,
                        const LobeOptions& options = {});

// Outgoing radiance under one RGB SG light: Σ_k weight_k ⊙ μ_L ∫ G_k G_L (eq. 4.7, closed form).
// With `visibility`, the triple product Σ_k weight_k ⊙ μ_L ∫ G_k G_L G_V.
glm::dvec3 ShadeUnderSgLight(std::span<const Lobe> lobes, const lighting::RgbSg& light,
                             const lighting::Sg* visibility = nullptr);
glm::dvec3 ShadeUnderSgLights(std::span<const Lobe> lobes, std::span<const lighting::RgbSg> lights);

// What a BRDF's GGX lobes leave out at one incident direction wi: the GGX specular term
// D F G / (4 n·wo) exactly (its cosine n·wi included) minus the sum of the term's non-cosine lobes
// at wi (their SGs evaluated there, weights included). `lobes` are that one term's, as AppendLobes
// made them for wo. 0 for BRDFs without GGX: their lobes are Gaussians like the NDFs they stand
// for. Why: GGX's tail falls as a power of θ_h, every SG's as a Gaussian, so a compact bright
// light 20–45° off the mirror direction (a studio softbox) lights a glossy GGX paint through a
// tail the two SGs hold only a few percent of.
glm::dvec3 GgxLobeResidual(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wi, const glm::dvec3& wo,
                           std::span<const Lobe> lobes);
// ∫ GgxLobeResidual(wi) G(wi) dwi for a sharp SG light G (amplitude included), what a renderer
// adds to the lobes' ∫ lobe × G: G as a 2D Gaussian of σ = 1/√λ in its tangent plane, integrated
// by the 7-point degree-5 rule (weight 1/2 at the axis, 1/12 at 2σ every 60° from the tangent
// normalize(axis × (0, 1, 0)), or × (1, 0, 0) when |axis·y| ≥ 0.9). One point at the axis alone
// was 18 % low on the windshield, where the softbox is near the mirror direction and the
// residual turns within the light.
glm::dvec3 GgxResidualUnderSgLight(const Brdf& brdf, const ShadingFrame& frame, const glm::dvec3& wo,
                                   std::span<const Lobe> lobes, const lighting::Sg& light);

// Building blocks, public for the renderer's shaders to mirror and for tests.
// λ of the SG fit of a GGX/Beckmann NDF of roughness α (see the header comment).
double NdfSgLambda(double alpha);
// GGX's D as two SGs in half-vector space around n (brdf.h's header): for α ≤ kGgxSgFadeBegin
// λ_k = kGgxSgLambdaScale[k] NdfSgLambda(α), μ_k = c kGgxSgWeight[k] / (π α²), c making ∫ D (n·h)
// = 1 exactly (c → 1 as α → 0); from there to kGgxSgFadeEnd blended into the one SG of
// NdfSgLambda (the wide SG's weight → 0). amplitude[1] is 0 from kGgxSgFadeEnd on.
struct GgxSgFit {
  double lambda[2];
  double amplitude[2];
};
GgxSgFit GgxSg(double alpha);
// The wide SG's share of the fit's ∫D: μ₁ I(λ₁) / Σ μ_k I(λ_k), I(λ) = (1 − e^{−2λ})/λ; 0.45 for
// α ≤ kGgxSgFadeBegin, 0 without a wide SG.
double GgxTailShare(const GgxSgFit& fit);
// Eq. 4.10: warps an SG in half-vector space to incident-direction space for the view wo.
lighting::Sg WarpToIncident(const lighting::Sg& half_vector_lobe, const glm::dvec3& wo);
// The clamped cosine around n as an SG.
lighting::Sg CosineSg(const glm::dvec3& n);
// coth λ − 1/λ: the mean of c·w under an SG of axis c and sharpness λ.
double SgMeanCosine(double lambda);
// The clamped cosine's mean under an SG of sharpness λ whose axis is at cos θ = z from n:
// ∫ G(w; c, λ) max(0, n·w) dw / ∫ G(w; c, λ). 1/4 at λ = 0; → max(0, z) as λ → ∞. Interpolated
// in ClampedCosineTable up to kClampedCosineLambdaMax; beyond, the SG is a narrow Gaussian
// against a nearly planar horizon: (coth λ − 1/λ)(z Φ(z√λ) + φ(z√λ)/√λ), within 1 % there.
double ClampedCosineMean(double z, double lambda);
// The same with Burley's grazing-light weight FL = (1 − n·w)⁵: ∫ G max(0, n·w) FL / ∫ G. Beyond
// the table, from the truncated moments of n·w as a Gaussian.
double ClampedCosineGrazingMean(double z, double lambda);
// The table: kClampedCosineRows rows of kClampedCosineZ of ClampedCosineMean, then as many of
// ClampedCosineGrazingMean; computed once by quadrature, the shader interpolates the same numbers.
const std::vector<double>& ClampedCosineTable();
// ∫ max(0, n·w) G(w) dw for an SG G (its amplitude included).
double ClampedCosineIntegral(const glm::dvec3& n, const lighting::Sg& g);
// ∫ of a clamped-cosine lobe (without its weight) against the SG g (amplitude included). Its
// linear and grazing factors are taken at the mean direction of `product`, the lobe's SG stand-in
// times the light: exact for the linear one (as LinearFactor), for the quadratic grazing one
// exact for a sharp light and within 1.5 % of the directional albedo under a uniform one.
double ClampedCosineLobeIntegral(const Lobe& lobe, const lighting::Sg& g, const lighting::Sg& product);
// 1 + linear·(the product's mean direction): a lobe's linear factor integrated against `product`.
double LinearFactor(const glm::dvec3& linear, const lighting::Sg& product);
// Cycles' principled diffuse (Burley 2015) relative to Lambert's 1/π: f_d π for n·wi, n·wo and
// wi·wo at roughness r (perceptual, in [0, 1]).
double PrincipledDiffuseFactor(double cos_i, double cos_o, double cos_io, double roughness);
// Its directional albedo (1/π) ∫ PrincipledDiffuseFactor (n·wi) dwi over the hemisphere, in closed
// form: 1 for a Lambertian surface; 1.04 for r = 1 at normal view, 1.25 at 78° from the normal.
double PrincipledDiffuseAlbedo(double cos_o, double roughness);

}  // namespace odvr::material
