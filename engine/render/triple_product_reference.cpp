// The CPU reference of TripleProductRenderer's shading stage: render_shade.comp's loop in double,
// built from the engine's own C++ pieces (material::AppendLobes, visibility::ConesForLobe,
// VoxelGrid::TraceCone, OverlapBins::Query, the SG integrals), so that the GPU port is held to
// them.
#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>

#include "core/constants.h"
#include "core/parallel.h"
#include "engine/lighting/sg.h"
#include "engine/render/passes/gpu_model.h"
#include "engine/render/triple_product_internal.h"

namespace odvr::render::detail {
namespace {

using lighting::Sg;

struct ConeSet {
  std::vector<visibility::Cone> cones;
  std::vector<double> visibility;
  std::vector<double> ground_lit;    // GroundLit along each cone
  std::vector<double> cosine_ratio;  // per cone; empty but for clamped-cosine lobes
  double lambda = 0;
  bool all_visible = true;
  bool ground_shadowed = false;  // some cone meets the ground where the car shadows it
};

double GroundLitFractionAt(double x, double z, const ReferenceInputs& in);

// uExactRayOffset: ExactRayOffset of the grid's voxels (with a BVH there is a grid).
float RayOffset(const ReferenceInputs& in) { return in.grid ? ExactRayOffset(in.grid->spec().voxel_size) : 0.f; }

// render_shade.comp's peakRaysVisibility: the share of the peak's rays (PeakRayDirections) from
// `offset` (ExactRayOffset) along the normal off the surface point that no triangle stops.
double PeakRaysVisibility(const glm::dvec3& surface, const glm::dvec3& normal, const lighting::RgbSg& peak,
                          const visibility::TriangleBvh& bvh, float offset) {
  const glm::vec3 o = glm::vec3(surface) + offset * glm::vec3(normal);
  const std::vector<glm::dvec3> rays = PeakRayDirections(peak.axis, peak.lambda);
  double lit = 0;
  for (const glm::dvec3& d : rays)
    lit += bvh.Occluded(o, glm::vec3(d), 0.f, std::numeric_limits<float>::infinity()) ? 0.0 : 1.0;
  return lit / static_cast<double>(rays.size());
}

// render_shade.comp's groundLit: the ground's lit fraction where a cone from p along dir meets it.
double GroundLit(const glm::dvec3& p, const glm::dvec3& dir, const ReferenceInputs& in) {
  if (!in.options.ground || !in.options.ground_shadows_bounce || dir.y >= 0 || p.y <= 0) return 1.0;
  const glm::dvec3 q = p - (p.y / dir.y) * dir;
  if (std::abs(q.x - in.ground_centre.x) > in.options.ground_half_size ||
      std::abs(q.z - in.ground_centre.y) > in.options.ground_half_size)
    return 1.0;
  if (in.ground_lit_map.width > 0) return SampleGroundLitMap(in.ground_lit_map, in.ground_lit_texels, q.x, q.z);
  return GroundLitFractionAt(q.x, q.z, in);
}

double GroundLitFractionAt(double x, double z, const ReferenceInputs& in) {
  const auto trace = [&](const glm::dvec3& o, const glm::dvec3& axis, double a) {
    return in.grid->TraceCone({glm::vec3(o), glm::vec3(axis), static_cast<float>(a)}, in.options.trace);
  };
  return GroundLitFraction(glm::dvec3(x, 0, z), *in.lighting, in.options.peak_cones, kGroundLitHalfAngle,
                           visibility::kMaxConeHalfAngle, trace, [&](const glm::dvec3& q, std::size_t k, double a) {
                             const lighting::RgbSg& pk = in.lighting->peaks[k];
                             return in.bvh ? PeakRaysVisibility(q, glm::dvec3(0, 1, 0), pk, *in.bvh, RayOffset(in))
                                           : trace(q, pk.axis, a);
                           });
}

// RenderOptions::ground_lit_map_texels: the grid render_shade.comp's pass uGroundTablePass == 2
// fills, traced at each texel's centre.
void FillGroundLitMap(ReferenceInputs* in, ThreadPool* pool) {
  in->ground_lit_map = {};
  in->ground_lit_texels.clear();
  if (!in->grid || !in->options.ground || !in->options.ground_shadows_bounce) return;
  in->ground_lit_map = GroundLitMapLayoutFor(in->grid->spec(), *in->lighting, in->options.peak_cones, in->ground_centre,
                                             in->options.ground_half_size, in->options.ground_lit_map_texels);
  const GroundLitMapLayout& m = in->ground_lit_map;
  in->ground_lit_texels.assign(m.texels(), 1.f);
  pool->ParallelFor(static_cast<long>(m.texels()), [&](long begin, long end) {
    for (long t = begin; t < end; ++t) {
      const double x = m.origin.x + static_cast<double>(t % m.width) * m.spacing;
      const double z = m.origin.y + static_cast<double>(t / m.width) * m.spacing;
      in->ground_lit_texels[static_cast<std::size_t>(t)] = static_cast<float>(GroundLitFractionAt(x, z, *in));
    }
  });
}

// render_shade.comp's coneCosineRatios: how much of a clamped-cosine lobe a cone holds against
// how much of its SG stand-in, ∫ max(0, n·w) V_i / ∫ G_cos V_i, so that the visible share weights
// the cones by the cosine itself (the stand-in is 17 % high at the normal, half the cosine's
// value at 80°).
std::vector<double> ConeCosineRatios(const glm::dvec3& n, const ConeSet& set) {
  std::vector<double> r;
  const Sg cosine{n, material::kCosineSgLambda, 1.0};
  for (const auto& c : set.cones) {
    const Sg v{c.axis, set.lambda, 1.0};
    const double sg = lighting::IntegralOfProduct(cosine, v);
    r.push_back(sg > 0 ? material::ClampedCosineIntegral(n, v) / sg : 0.0);
  }
  return r;
}

ConeSet TraceLobeCones(const Sg& lobe, bool cosine, const glm::dvec3& p, const ReferenceInputs& in) {
  visibility::ConeSubsampleOptions co = in.options.cones;
  co.rings = in.options.cone_rings;
  ConeSet set;
  set.cones = visibility::ConesForLobe(Sg{lobe.axis, lobe.lambda, 1.0}, co);
  set.lambda = lighting::LambdaForHalfValueAngle(set.cones.front().half_angle);
  for (const auto& c : set.cones) {
    const double v = in.grid ? in.grid->TraceCone({glm::vec3(p), glm::vec3(c.axis), static_cast<float>(c.half_angle)},
                                                  in.options.trace)
                             : 1.0;
    const double g = in.grid ? GroundLit(p, c.axis, in) : 1.0;
    set.visibility.push_back(v);
    set.ground_lit.push_back(g);
    set.all_visible = set.all_visible && v >= 1.0;
    set.ground_shadowed = set.ground_shadowed || g < 1.0;
  }
  if (cosine) set.cosine_ratio = ConeCosineRatios(lobe.axis, set);
  return set;
}

// The product of two unit SGs with its amplitude as a logarithm, r − Λ = −λ1λ2|c1 − c2|²/(r + Λ)
// (sg_integral.glsl): a sharp product far from a cone has an amplitude below double's range.
struct LogProduct {
  glm::dvec3 axis;
  double lambda, log_amplitude;
};
LogProduct ProductLog(const glm::dvec3& c1, double l1, const glm::dvec3& c2, double l2) {
  const glm::dvec3 s = l1 * c1 + l2 * c2;
  const double r = glm::length(s), sum = l1 + l2;
  const glm::dvec3 d = c1 - c2;
  return {r > 1e-12 ? s / r : c1, r, sum > 0 ? -l1 * l2 * glm::dot(d, d) / (r + sum) : 0.0};
}

// Σ v_i ∫P V_i / Σ ∫P V_i (see triple_product_renderer.h), exponents shifted by their maximum;
// ground_loss: Σ v_i (1 − g_i) ∫P V_i / Σ ∫P V_i, the share the car's shadow takes off the
// ground's bounce (render_shade.comp's visibleShareOf).
double VisibleShare(const Sg& product, const ConeSet& set, bool ground_loss = false) {
  const auto value = [&](std::size_t i) { return set.visibility[i] * (ground_loss ? 1.0 - set.ground_lit[i] : 1.0); };
  std::vector<double> log_w(set.cones.size());
  double top = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < set.cones.size(); ++i) {
    const LogProduct q = ProductLog(product.axis, product.lambda, set.cones[i].axis, set.lambda);
    // ∫ of a unit SG of λ is 2π (1 − e^{−2λ})/λ.
    const double shape = q.lambda < 1e-6 ? 2.0 : -std::expm1(-2.0 * q.lambda) / q.lambda;
    log_w[i] = q.log_amplitude + std::log(shape);
    if (!set.cosine_ratio.empty())
      log_w[i] += set.cosine_ratio[i] > 0 ? std::log(set.cosine_ratio[i]) : -std::numeric_limits<double>::infinity();
    top = std::max(top, log_w[i]);
  }
  if (!(top > -std::numeric_limits<double>::infinity())) return value(0);
  double num = 0, den = 0;
  for (std::size_t i = 0; i < set.cones.size(); ++i) {
    const double w = std::exp(log_w[i] - top);
    num += w * value(i);
    den += w;
  }
  return den > 0 ? num / den : value(0);
}

// The unshadowed ∫ lobe × light (the lobe's SG of unit amplitude, or for a clamped-cosine lobe
// material::ClampedCosineLobeIntegral), without the lobe's weight.
double FullIntegral(const material::Lobe& lobe, const Sg& l) {
  const Sg unit{lobe.sg.axis, lobe.sg.lambda, 1.0};
  const Sg product = lighting::Product(unit, l);
  if (lobe.clamped_cosine) return material::ClampedCosineLobeIntegral(lobe, l, product);
  return lighting::IntegralOfProduct(unit, l) * material::LinearFactor(lobe.linear, product);
}

// lobe_share ≥ 0: the visible share of the whole lobe, for every light (a GGX tail, ShadeLobe).
void AddLight(const material::Lobe& lobe, const lighting::RgbSg& light, const ConeSet& set, double lobe_share,
              glm::dvec3* shaded, glm::dvec3* unshadowed, PixelCounts* count) {
  const Sg l{light.axis, light.lambda, 1.0};
  const double full = FullIntegral(lobe, l);
  double share = 1;
  if (!set.all_visible && lobe_share >= 0) {
    share = lobe_share;
  } else if (!set.all_visible) {
    const LogProduct prod = ProductLog(lobe.sg.axis, lobe.sg.lambda, l.axis, l.lambda);
    share = VisibleShare(Sg{prod.axis, prod.lambda, 1.0}, set);
    count->triples += static_cast<unsigned>(set.cones.size());
  }
  *shaded += glm::dvec3(light.amplitude) * (full * share);
  *unshadowed += glm::dvec3(light.amplitude) * full;
  count->sgs += 1;
}

void ShadeLobe(const material::Lobe& lobe, const ConeSet& set, const ReferenceInputs& in, glm::dvec3* shaded,
               glm::dvec3* unshadowed, PixelCounts* count) {
  const PreparedLighting& L = *in.lighting;
  // A GGX tail (material::Lobe::tail_share) is seen through the lobe's own visible share, not one
  // per light (render_shade.comp's emitLobe says why), and only by the lighting levels it needs.
  const bool tail = lobe.tail_share > 0;
  double lobe_share = -1;
  if (tail && !set.all_visible) {
    lobe_share = VisibleShare(Sg{lobe.sg.axis, lobe.sg.lambda, 1.0}, set);
    count->triples += static_cast<unsigned>(set.cones.size());
  }
  if (L.constant != glm::vec3(0))
    AddLight(lobe, {{0, 1, 0}, 0.0, L.constant}, set, lobe_share, shaded, unshadowed, count);
  if (in.bins && !L.srbfs.empty()) {
    // The lists are sorted by global index, so by level: a tail (and with depth_per_lobe every
    // lobe) stops below its deepest level.
    const int end =
        tail || in.options.depth_per_lobe
            ? lighting::GlobalSrbfIndex(in.bins->MaxLevel(lobe.sg.lambda, tail ? lobe.tail_share : 1.0) + 1, 0)
            : std::numeric_limits<int>::max();
    for (int g : in.bins->Query(L.env_from_world * lobe.sg.axis, lobe.sg.lambda)) {
      if (g >= end) break;
      const auto& s = L.srbfs[static_cast<std::size_t>(g)];
      if (s.amplitude == glm::vec3(0)) continue;
      AddLight(lobe, s, set, lobe_share, shaded, unshadowed, count);
    }
  }
  const std::size_t first = in.options.peak_cones ? TripleProductRenderer::kMaxPeakCones : 0;
  for (std::size_t k = first; k < L.peaks.size(); ++k)
    AddLight(lobe, L.peaks[k], set, lobe_share, shaded, unshadowed, count);
}

void ShadePeaks(const material::Lobe& lobe, const std::vector<double>& peak_visibility, const ReferenceInputs& in,
                glm::dvec3* shaded, glm::dvec3* unshadowed) {
  if (!in.options.peak_cones) return;
  const auto& peaks = in.lighting->peaks;
  for (std::size_t k = 0; k < std::min<std::size_t>(peaks.size(), TripleProductRenderer::kMaxPeakCones); ++k) {
    const double full = FullIntegral(lobe, Sg{peaks[k].axis, peaks[k].lambda, 1.0});
    *shaded += glm::dvec3(peaks[k].amplitude) * (full * peak_visibility[k]);
    *unshadowed += glm::dvec3(peaks[k].amplitude) * full;
  }
}

// A peak's visibility from a surface point: its rays from `surface` (RenderOptions::
// exact_peak_shadows), or its cone from `p`, the cones' origin off the surface; 1 without geometry.
double PeakVisibility(const glm::dvec3& p, const glm::dvec3& surface, const glm::dvec3& normal,
                      const lighting::RgbSg& peak, const ReferenceInputs& in) {
  if (in.bvh) return PeakRaysVisibility(surface, normal, peak, *in.bvh, RayOffset(in));
  if (!in.grid) return 1.0;
  const double a = std::min(HalfValueAngle(peak.lambda), visibility::kMaxConeHalfAngle);
  return in.grid->TraceCone({glm::vec3(p), glm::vec3(peak.axis), static_cast<float>(a)}, in.options.trace);
}

// `p` the cones' origin; `surface` and `normal` the point shaded, where an exact ray starts
// (RenderOptions::exact_peak_shadows).
std::vector<double> TracePeakCones(const glm::dvec3& p, const glm::dvec3& surface, const glm::dvec3& normal,
                                   const ReferenceInputs& in, PixelCounts* count) {
  const auto& peaks = in.lighting->peaks;
  const std::size_t traced = std::min<std::size_t>(peaks.size(), TripleProductRenderer::kMaxPeakCones);
  std::vector<double> v(traced, 1.0);
  if (!in.options.peak_cones) return v;
  if (!in.grid) {
    count->cones += static_cast<unsigned>(traced);
    return v;
  }
  for (std::size_t k = 0; k < traced; ++k) {
    v[k] = PeakVisibility(p, surface, normal, peaks[k], in);
    count->cones += 1;
  }
  return v;
}

// A surface's glTF metallic-roughness: the G-buffer's (its textures) or a material's means.
struct GltfSample {
  glm::dvec3 base{1};
  double metallic = 0, roughness = 1;
};

GltfSample GltfAt(const GBuffer& g, std::size_t idx) {
  return {glm::dvec3(g.base[4 * idx], g.base[4 * idx + 1], g.base[4 * idx + 2]), g.base[4 * idx + 3],
          g.normal[4 * idx + 3]};
}

// The lobes of a surface's material: the override's terms, or its glTF metallic-roughness `gltf`.
// `term_of` gets each lobe's term; `on_term(brdf, own lobes)` is called after each term's lobes
// are appended.
template <class OnTerm>
void AppendMaterialLobes(const ReferenceInputs& in, const GltfSample& gltf, int material,
                         const material::ShadingFrame& frame, const glm::dvec3& wo, std::vector<material::Lobe>* lobes,
                         std::vector<int>* term_of, const OnTerm& on_term) {
  const auto add = [&](const material::Brdf& brdf, int term) {
    const std::size_t first = lobes->size();
    material::AppendLobes(brdf, frame, wo, lobes, in.options.lobes);
    term_of->resize(lobes->size(), term);
    on_term(brdf, std::span<const material::Lobe>(lobes->data() + first, lobes->size() - first));
  };
  const MaterialTermList& list = (*in.materials)[static_cast<std::size_t>(material)];
  int term = 0;
  if (list.from_gbuffer) add(material::MetallicRoughness{gltf.base, gltf.metallic, gltf.roughness}, term++);
  for (const material::Brdf& brdf : list.terms) add(brdf, term++);
}

// render_shade.comp's gbufferAt: −1 where world point x is off the picture or behind the camera;
// else its sample *q, and 1 with *behind = how far x lies behind the car surface there along the
// camera's axis, 0 where the sample shows no car.
int GbufferAt(const ReferenceInputs& in, const glm::dvec3& x, std::size_t* q, double* behind) {
  const GBuffer& g = *in.gbuffer;
  const glm::dvec3 c = glm::transpose(in.camera.world_from_camera) * (x - in.camera.position);
  if (!(c.z > 1e-4)) return -1;  // behind the camera (or not a number)
  const double focal = in.camera.focal_px();
  const double px = std::floor(c.x / c.z * focal + 0.5 * g.width), py = std::floor(c.y / c.z * focal + 0.5 * g.height);
  if (!(px >= 0 && py >= 0 && px < g.width && py < g.height)) return -1;
  *q = static_cast<std::size_t>(py) * static_cast<std::size_t>(g.width) + static_cast<std::size_t>(px);
  if (g.position[4 * *q + 3] < 0.5f) return 0;
  const glm::dvec3 surface(g.position[4 * *q], g.position[4 * *q + 1], g.position[4 * *q + 2]);
  *behind = c.z - glm::dot(in.camera.world_from_camera[2], surface - in.camera.position);
  return 1;
}

double BounceThickness(const ReferenceInputs& in) {
  return in.options.bounce_thickness_voxels * in.grid->spec().voxel_size;
}

// render_shade.comp's bounceHit: the first car surface the G-buffer shows behind o + t d, t a
// multiple of the step, by less than the thickness along the camera's axis.
bool BounceHit(const ReferenceInputs& in, const glm::dvec3& o, const glm::dvec3& d, std::size_t* hit) {
  const double step = in.options.bounce_step_voxels * in.grid->spec().voxel_size, thickness = BounceThickness(in);
  for (int s = 1; s <= in.options.bounce_steps; ++s) {
    double behind = 0;
    const int at = GbufferAt(in, o + (step * s) * d, hit, &behind);
    if (at < 0) return false;
    if (at > 0 && behind > 0 && behind < thickness) return true;
  }
  return false;
}

// What G-buffer sample q emits (none where the G-buffer has no emission channel).
glm::dvec3 Emitted(const GBuffer& g, std::size_t q) {
  if (4 * q + 2 >= g.emission.size()) return glm::dvec3(0);
  return glm::dvec3(g.emission[4 * q], g.emission[4 * q + 1], g.emission[4 * q + 2]);
}

// render_shade.comp's surfaceBounceRadiance: what a car surface at x, normal n, of `material`
// sends along wo_in, from its specular lobes under the constant, the coarse SRBFs and the peaks
// (shadowed from there), plus what it emits.
glm::dvec3 SurfaceBounceRadiance(const ReferenceInputs& in, const glm::dvec3& x, const glm::dvec3& n, int material,
                                 const GltfSample& gltf, const glm::dvec3& emitted, const glm::dvec3& wo_in) {
  if (material < 0 || material >= static_cast<int>(in.materials->size())) return glm::dvec3(0);
  if (glm::dot(n, wo_in) <= 0) return emitted;
  const PreparedLighting& L = *in.lighting;
  std::vector<double> visible(std::min<std::size_t>(L.peaks.size(), TripleProductRenderer::kMaxPeakCones), 1.0);
  const glm::dvec3 origin = x + n * (in.grid ? in.options.surface_offset_voxels * in.grid->spec().voxel_size : 0.0);
  for (std::size_t k = 0; k < visible.size(); ++k) visible[k] = PeakVisibility(origin, x, n, L.peaks[k], in);
  std::vector<material::Lobe> lobes;
  std::vector<int> term_of;
  AppendMaterialLobes(in, gltf, material, material::ShadingFrame::FromNormal(n), wo_in, &lobes, &term_of,
                      [](const material::Brdf&, std::span<const material::Lobe>) {});
  const int srbfs = BounceSrbfCount(L);
  glm::dvec3 radiance(0);
  for (const material::Lobe& lobe : lobes) {
    if (lobe.clamped_cosine) continue;
    glm::dvec3 light = glm::dvec3(L.constant) * FullIntegral(lobe, Sg{{0, 1, 0}, 0.0, 1.0});
    for (int j = 0; j < srbfs; ++j) {
      const lighting::RgbSg& s = L.srbfs[static_cast<std::size_t>(j)];
      if (s.amplitude != glm::vec3(0)) light += glm::dvec3(s.amplitude) * FullIntegral(lobe, Sg{s.axis, s.lambda, 1.0});
    }
    for (std::size_t k = 0; k < L.peaks.size(); ++k)
      light += glm::dvec3(L.peaks[k].amplitude) * (k < visible.size() ? visible[k] : 1.0) *
               FullIntegral(lobe, Sg{L.peaks[k].axis, L.peaks[k].lambda, 1.0});
    radiance += lobe.weight * lobe.sg.amplitude * light;
  }
  return glm::max(radiance, glm::dvec3(0)) + emitted;
}

// render_shade.comp's bounceRadiance: SurfaceBounceRadiance of G-buffer sample q.
glm::dvec3 BounceRadiance(const ReferenceInputs& in, std::size_t q, const glm::dvec3& wo_in) {
  const GBuffer& g = *in.gbuffer;
  const int material = static_cast<int>(std::lround(g.position[4 * q + 3])) - 1;
  const glm::dvec3 x(g.position[4 * q], g.position[4 * q + 1], g.position[4 * q + 2]);
  const glm::dvec3 n = glm::normalize(glm::dvec3(g.normal[4 * q], g.normal[4 * q + 1], g.normal[4 * q + 2]));
  return SurfaceBounceRadiance(in, x, n, material, GltfAt(g, q), Emitted(g, q), wo_in);
}

// render_shade.comp's gbufferShows: the G-buffer sample that shows world point x, within the
// bounce's thickness along the camera's axis.
bool GbufferShows(const ReferenceInputs& in, const glm::dvec3& x, std::size_t* q) {
  double behind = 0;
  return GbufferAt(in, x, q, &behind) > 0 && std::abs(behind) < BounceThickness(in);
}

// render_shade.comp's triangleBounce: what the car sends back along −d from the first triangle
// the ray o + t d hits — the G-buffer's surface there when the camera sees it, else the
// triangle's own (normals interpolated and turned to the ray, its material's means).
bool TriangleBounce(const ReferenceInputs& in, const glm::dvec3& o, const glm::dvec3& d, glm::dvec3* radiance) {
  *radiance = glm::dvec3(0);
  visibility::TriangleBvh::Hit hit;
  if (!in.bvh->ClosestHit(glm::vec3(o), glm::vec3(d), 0.f, 3.0e38f, &hit)) return false;
  const glm::dvec3 x = o + static_cast<double>(hit.t) * d;
  std::size_t q = 0;
  if (GbufferShows(in, x, &q)) {
    *radiance = BounceRadiance(in, q, -d);
    return true;
  }
  const std::vector<glm::vec4>& rows = in.model->bvh_shading();
  const std::size_t row =
      static_cast<std::size_t>(in.model->bvh_shading_first_triangle_row()) + 3 * static_cast<std::size_t>(hit.triangle);
  const glm::vec4 n0 = rows[row], n1 = rows[row + 1], n2 = rows[row + 2];
  glm::dvec3 n = glm::dvec3((1.f - hit.u - hit.v) * glm::vec3(n0) + hit.u * glm::vec3(n1) + hit.v * glm::vec3(n2));
  const std::vector<glm::vec4>& tris = in.bvh->triangles();
  const std::size_t v = 3 * static_cast<std::size_t>(hit.triangle);
  const glm::dvec3 face = glm::cross(glm::dvec3(tris[v + 1] - tris[v]), glm::dvec3(tris[v + 2] - tris[v]));
  n = glm::dot(n, n) > 1e-12 ? glm::normalize(n) : glm::normalize(face);
  if (glm::dot(n, d) > 0) n = -n;
  const int material = static_cast<int>(std::lround(n0.w));
  const std::size_t m =
      static_cast<std::size_t>(GpuModel::kBvhShadingRowsPerMaterial) * static_cast<std::size_t>(material);
  if (material < 0 || m + 1 >= rows.size()) return true;
  const GltfSample gltf{glm::dvec3(rows[m]), rows[m].w, rows[m + 1].w};
  *radiance = SurfaceBounceRadiance(in, x, n, material, gltf, glm::dvec3(rows[m + 1]), -d);
  return true;
}

}  // namespace

std::vector<glm::dvec3> PeakRayDirections(const glm::dvec3& axis, double lambda) {
  const double a = HalfValueAngle(lambda);
  if (a < kPeakRingMinHalfAngle) return {axis};
  // The same basis and ring as render_shade.comp's tracePeakCones builds, in float there.
  const glm::dvec3 helper = std::abs(axis.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  const glm::dvec3 e1 = glm::normalize(glm::cross(helper, axis)), e2 = glm::cross(axis, e1);
  const double r = std::min(kPeakRingScale * a, visibility::kMaxConeHalfAngle);
  std::vector<glm::dvec3> rays = {axis};
  for (int j = 0; j < 6; ++j) {
    const double phi = std::numbers::pi * j / 3;
    rays.push_back(glm::normalize(std::cos(r) * axis + std::sin(r) * (std::cos(phi) * e1 + std::sin(phi) * e2)));
  }
  return rays;
}

double HalfValueAngle(double lambda) {
  return lambda > std::log(2.0) / 2 ? lighting::HalfValueAngleForLambda(lambda) : kPi;
}

void ShadeReference(const ReferenceInputs& given, RenderResult* result, std::vector<PixelCounts>* counts) {
  static ThreadPool pool;
  ReferenceInputs in = given;
  FillGroundLitMap(&in, &pool);
  const GBuffer& g = *in.gbuffer;
  const int w = g.width, h = g.height;
  result->car = sphere::EquirectImage(w, h, 0.f);
  result->shadow = sphere::EquirectImage(w, h, 1.f);
  result->car_alpha.assign(static_cast<std::size_t>(w) * h, 0.f);
  result->ground_mask.assign(static_cast<std::size_t>(w) * h, 0.f);
  counts->assign(static_cast<std::size_t>(w) * h, {});
  const int material_count = static_cast<int>(in.materials->size());
  const bool bounce = in.options.specular_bounce && in.grid;
  const bool ambient = in.options.ambient_bounce && in.grid;
  pool.ParallelFor(
      static_cast<long>(w) * h,
      [&](long begin, long end) {
        std::vector<material::Lobe> lobes;
        std::vector<int> lobe_term;
        for (long i = begin; i < end; ++i) {
          const auto idx = static_cast<std::size_t>(i);
          const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
          PixelCounts& count = (*counts)[idx];
          const int material = static_cast<int>(std::lround(g.position[4 * idx + 3])) - 1;
          if (material >= 0 && material < material_count) {
            const glm::dvec3 p(g.position[4 * idx], g.position[4 * idx + 1], g.position[4 * idx + 2]);
            const glm::dvec3 n =
                glm::normalize(glm::dvec3(g.normal[4 * idx], g.normal[4 * idx + 1], g.normal[4 * idx + 2]));
            const material::ShadingFrame frame = material::ShadingFrame::FromNormal(n);
            const glm::dvec3 wo = glm::normalize(in.camera.position - p);
            lobes.clear();
            lobe_term.clear();
            const glm::dvec3 origin =
                p + n * (in.grid ? in.options.surface_offset_voxels * in.grid->spec().voxel_size : 0.0);
            const std::vector<double> peak_v = TracePeakCones(origin, p, n, in, &count);
            // Per traced peak: Σ over the lobes of ∫ lobe × peak, plus what the GGX lobes leave
            // out under it (material::GgxResidualUnderSgLight).
            std::vector<glm::dvec3> peak_sum(in.options.peak_cones ? peak_v.size() : 0, glm::dvec3(0));
            AppendMaterialLobes(
                in, GltfAt(g, idx), material, frame, wo, &lobes, &lobe_term,
                [&](const material::Brdf& brdf, std::span<const material::Lobe> own) {
                  for (std::size_t k = 0; k < peak_sum.size(); ++k) {
                    const auto& pk = in.lighting->peaks[k];
                    peak_sum[k] += material::GgxResidualUnderSgLight(brdf, frame, wo, own, Sg{pk.axis, pk.lambda, 1.0});
                  }
                });
            // RenderOptions::specular_bounce: per term, the light its specular lobes lose to the
            // car and the luminance-weighted mean of their axes (render_shade.comp's emitLobe).
            glm::dvec3 bounce_weight[kBounceTerms] = {glm::dvec3(0), glm::dvec3(0)};
            glm::dvec3 bounce_axis[kBounceTerms] = {glm::dvec3(0), glm::dvec3(0)};
            glm::dvec3 radiance(0);
            for (std::size_t li = 0; li < lobes.size(); ++li) {
              const material::Lobe& lobe = lobes[li];
              const Sg unit{lobe.sg.axis, lobe.sg.lambda, 1.0};
              const bool cosine = lobe.clamped_cosine;
              const ConeSet set = TraceLobeCones(unit, cosine, origin, in);
              glm::dvec3 shaded(0), unshadowed(0);
              ShadeLobe(lobe, set, in, &shaded, &unshadowed, &count);
              if (set.ground_shadowed) {
                // render_shade.comp's emitLobe: the ground's own radiance over the cones that
                // meet its shadow, whatever SGs carry the lighting across the horizon.
                // Never below 0: a lobe cannot lose more light than it has.
                const glm::dvec3 loss = glm::dvec3(in.lighting->GroundRadiance(in.options.peak_cones)) *
                                        (FullIntegral(lobe, Sg{{0, 1, 0}, 0.0, 1.0}) * VisibleShare(unit, set, true));
                shaded -= glm::min(loss, glm::max(shaded, glm::dvec3(0)));
                count.triples += static_cast<unsigned>(set.cones.size());
              }
              // A clamped-cosine lobe's weight is the whole of it; an SG lobe's amplitude is apart.
              const glm::dvec3 weight = lobe.weight * (cosine ? 1.0 : lobe.sg.amplitude);
              radiance += weight * shaded;
              if (ambient && cosine && !set.all_visible) {
                // RenderOptions::ambient_bounce (render_shade.comp's emitLobe): the occluded part
                // of the lobe sees car surfaces sending a v L̄ / (1 − a (1 − v)), a = π weight.
                const double v = VisibleShare(unit, set);
                const glm::dvec3 a = glm::min(kPi * weight, glm::dvec3(1.0));
                const glm::dvec3 occluder = a * v * glm::dvec3(in.lighting->mean_radiance) /
                                            glm::max(glm::dvec3(1.0) - a * (1.0 - v), glm::dvec3(1e-4));
                radiance += weight * occluder * (FullIntegral(lobe, Sg{{0, 1, 0}, 0.0, 1.0}) * (1.0 - v));
                count.triples += static_cast<unsigned>(set.cones.size());
              }
              if (bounce && !cosine && !set.all_visible) {  // GGX tails too (render_shade.comp)
                const glm::dvec3 lost = weight * (lighting::Integral(unit) * (1.0 - VisibleShare(unit, set)));
                const int t = std::min(lobe_term[li], kBounceTerms - 1);
                bounce_weight[t] += lost;
                bounce_axis[t] += lobe.sg.axis * glm::dot(lost, glm::dvec3(0.2126, 0.7152, 0.0722));
                // A tail's share is ShadeLobe's, counted there; the GPU reuses it.
                if (lobe.tail_share <= 0) count.triples += static_cast<unsigned>(set.cones.size());
              }
              for (std::size_t k = 0; k < peak_sum.size(); ++k)
                peak_sum[k] +=
                    weight * FullIntegral(lobe, Sg{in.lighting->peaks[k].axis, in.lighting->peaks[k].lambda, 1.0});
              count.lobes += 1;
              count.cones += static_cast<unsigned>(set.cones.size());
            }
            // The residual is the BRDF at seven directions: against a peak wider than a sharp
            // lobe it can overshoot below 0, which no light does.
            for (std::size_t k = 0; k < peak_sum.size(); ++k)
              radiance +=
                  glm::max(glm::dvec3(in.lighting->peaks[k].amplitude) * peak_sum[k], glm::dvec3(0)) * peak_v[k];
            for (int t = 0; t < kBounceTerms; ++t) {
              if (!(glm::length(bounce_axis[t]) > 0)) continue;
              const glm::dvec3 d = glm::normalize(bounce_axis[t]);
              const glm::dvec3 o = p + static_cast<double>(RayOffset(in)) * n;
              std::size_t hit = 0;
              glm::dvec3 bounced(0);
              if (in.bvh ? TriangleBounce(in, o, d, &bounced) : BounceHit(in, o, d, &hit))
                radiance += bounce_weight[t] * (in.bvh ? bounced : BounceRadiance(in, hit, -d));
            }
            radiance += Emitted(g, idx);
            for (int c = 0; c < 3; ++c) result->car.rgb[3 * idx + c] = static_cast<float>(radiance[c]);
            result->car_alpha[idx] = 1.f;
          } else if (in.options.ground) {
            const glm::dvec3 dir = in.camera.Ray(x + 0.5, y + 0.5);
            const double t = dir.y < 0 ? -in.camera.position.y / dir.y : -1.0;
            glm::dvec3 p = in.camera.position + t * dir;
            if (!(t > 0 && std::abs(p.x - in.ground_centre.x) <= in.options.ground_half_size &&
                  std::abs(p.z - in.ground_centre.y) <= in.options.ground_half_size))
              continue;
            p.y = 0;
            result->ground_mask[idx] = 1.f;
            const material::Lobe up{material::CosineSg({0, 1, 0}), glm::dvec3(1), glm::dvec3(0), true};
            const ConeSet set = TraceLobeCones({up.sg.axis, up.sg.lambda, 1.0}, true, p, in);
            const std::vector<double> peak_v = TracePeakCones(p, p, {0, 1, 0}, in, &count);
            count.cones += static_cast<unsigned>(set.cones.size());
            bool lit = set.all_visible;
            for (double v : peak_v) lit = lit && v >= 1.0;
            if (lit) continue;
            glm::dvec3 shaded(0), unshadowed(0);
            ShadeLobe(up, set, in, &shaded, &unshadowed, &count);
            ShadePeaks(up, peak_v, in, &shaded, &unshadowed);
            count.lobes += 1;
            for (int c = 0; c < 3; ++c)
              result->shadow.rgb[3 * idx + c] =
                  unshadowed[c] > 0 ? static_cast<float>(std::clamp(shaded[c] / unshadowed[c], 0.0, 1.0)) : 1.f;
          }
        }
      },
      16);
}

std::vector<float> SupersampleWeights(int k) {
  // Cycles' filter_width 1.5, which it doubles for Blackman-Harris: the window reaches ±1.5 px.
  constexpr double kHalfWidth = 1.5, kTwoPi = 6.283185307179586;
  std::vector<float> weights(static_cast<std::size_t>(3 * k), 0.f);
  for (int j = -k; j < 2 * k; ++j) {
    const double t = (((j + 0.5) / k - 0.5) / kHalfWidth + 1) / 2;  // 0..1 across the window
    if (t <= 0 || t >= 1) continue;
    const double a = kTwoPi * t;
    weights[static_cast<std::size_t>(j + k)] =
        static_cast<float>(0.35875 - 0.48829 * std::cos(a) + 0.14128 * std::cos(2 * a) - 0.01168 * std::cos(3 * a));
  }
  return weights;
}

void ResolveSupersampled(const RenderResult& shaded, int k, int width, int height, RenderResult* out,
                         const std::vector<std::uint8_t>* flags) {
  const int sw = shaded.car.width, sh = shaded.car.height;
  // The sample that was shaded for sample (x, y).
  const auto shaded_index = [&](int x, int y) {
    if (flags && !(*flags)[static_cast<std::size_t>(y / k) * width + x / k]) {
      x = x / k * k + k / 2;
      y = y / k * k + k / 2;
    }
    return static_cast<std::size_t>(y) * sw + x;
  };
  const std::vector<float> weight = SupersampleWeights(k);
  out->car = sphere::EquirectImage(width, height, 0.f);
  out->shadow = sphere::EquirectImage(width, height, 1.f);
  out->car_alpha.assign(static_cast<std::size_t>(width) * height, 0.f);
  out->ground_mask.assign(static_cast<std::size_t>(width) * height, 0.f);
  for (int y_out = 0; y_out < height; ++y_out)
    for (int x_out = 0; x_out < width; ++x_out) {
      // float sums in the shader's order (rows outer, columns inner), so both paths round alike.
      float w_sum = 0, alpha = 0, ground = 0, uncovered = 0;
      glm::vec3 car(0), shadow(0);
      for (int j = 0; j < 3 * k; ++j) {
        const int y = k * y_out - k + j;
        if (y < 0 || y >= sh || weight[static_cast<std::size_t>(j)] == 0.f) continue;
        for (int i = 0; i < 3 * k; ++i) {
          const int x = k * x_out - k + i;
          if (x < 0 || x >= sw || weight[static_cast<std::size_t>(i)] == 0.f) continue;
          const float w = weight[static_cast<std::size_t>(j)] * weight[static_cast<std::size_t>(i)];
          const std::size_t s = shaded_index(x, y);
          const float a = shaded.car_alpha[s];
          w_sum += w;
          alpha += w * a;
          ground += w * shaded.ground_mask[s];
          uncovered += w * (1 - a);
          const float* c = &shaded.car.rgb[3 * s];
          const float* r = &shaded.shadow.rgb[3 * s];
          car += w * a * glm::vec3(c[0], c[1], c[2]);
          shadow += w * (1 - a) * glm::vec3(r[0], r[1], r[2]);
        }
      }
      const std::size_t o = static_cast<std::size_t>(y_out) * width + x_out;
      out->car_alpha[o] = alpha / w_sum;
      out->ground_mask[o] = ground / w_sum;
      if (alpha > 0) car /= alpha;
      if (uncovered > 0)
        shadow /= uncovered;
      else
        shadow = glm::vec3(1);
      for (int c = 0; c < 3; ++c) {
        out->car.rgb[3 * o + c] = car[c];
        out->shadow.rgb[3 * o + c] = shadow[c];
      }
    }
}

std::vector<std::uint8_t> FlagPixels(const GBuffer& g, const RenderResult& shaded, int k, int width, int height,
                                     float contrast, bool neighbour_reps) {
  const int sw = g.width;
  const auto luma = [](const float* c) { return c[0] * 0.2126f + c[1] * 0.7152f + c[2] * 0.0722f; };
  const auto centre = [&](int x, int y) { return static_cast<std::size_t>(y * k + k / 2) * sw + (x * k + k / 2); };
  std::vector<std::uint8_t> flags(static_cast<std::size_t>(width) * height, 0);
  // Whether pixel (x, y)'s samples, or its centre sample, lie within the G-buffer: a block cut by
  // an odd edge (shading_rate 2) is shaded whole, and its centre is no neighbour's to compare.
  const auto whole = [&](int x, int y) { return x * k + k - 1 < sw && y * k + k - 1 < g.height; };
  const auto has_centre = [&](int x, int y) { return x * k + k / 2 < sw && y * k + k / 2 < g.height; };
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      if (!whole(x, y)) {
        flags[static_cast<std::size_t>(y) * width + x] = 1;
        continue;
      }
      const std::size_t c = centre(x, y);
      const float material = g.position[4 * c + 3];
      const glm::vec3 n(g.normal[4 * c], g.normal[4 * c + 1], g.normal[4 * c + 2]);
      bool flag = false;
      for (int sy = 0; sy < k; ++sy)
        for (int sx = 0; sx < k; ++sx) {
          const std::size_t s = static_cast<std::size_t>(y * k + sy) * sw + (x * k + sx);
          const glm::vec3 ns(g.normal[4 * s], g.normal[4 * s + 1], g.normal[4 * s + 2]);
          if (g.position[4 * s + 3] != material || (material > 0 && glm::dot(ns, n) < kSupersampleNormalCos))
            flag = true;
        }
      if (neighbour_reps) {
        if (x == 0 || y == 0) flag = true;
        for (int i = 1; i < 4 && !flag; ++i) {
          const std::size_t s = centre(x - (i & 1), y - (i >> 1));
          const glm::vec3 ns(g.normal[4 * s], g.normal[4 * s + 1], g.normal[4 * s + 2]);
          if (g.position[4 * s + 3] != material || (material > 0 && glm::dot(ns, n) < kSupersampleNormalCos))
            flag = true;
        }
      }
      const float car = luma(&shaded.car.rgb[3 * c]), shadow = luma(&shaded.shadow.rgb[3 * c]);
      constexpr int kDirections[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
      for (const auto& d : kDirections) {
        const int ax = x - d[0], ay = y - d[1], bx = x + d[0], by = y + d[1];
        if (std::min({ax, ay, bx, by}) < 0 || std::max(ax, bx) >= width || std::max(ay, by) >= height) continue;
        if (!has_centre(ax, ay) || !has_centre(bx, by)) continue;
        const std::size_t a = centre(ax, ay), b = centre(bx, by);
        const float ca = luma(&shaded.car.rgb[3 * a]), cb = luma(&shaded.car.rgb[3 * b]);
        if (std::abs(ca + cb - 2.0f * car) > contrast * std::max({car, ca, cb}) ||
            std::abs(luma(&shaded.shadow.rgb[3 * a]) + luma(&shaded.shadow.rgb[3 * b]) - 2.0f * shadow) > contrast)
          flag = true;
      }
      flags[static_cast<std::size_t>(y) * width + x] = flag ? 1 : 0;
    }
  return flags;
}

void FillHalfRate(const std::vector<std::uint8_t>& block_flags, RenderResult* r) {
  const int w = r->car.width, h = r->car.height, bw = (w + 1) / 2;
  RenderResult& out = *r;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int bx = x / 2, by = y / 2, ox = x - 2 * bx, oy = y - 2 * by;
      if ((ox == 1 && oy == 1) || block_flags[static_cast<std::size_t>(by) * bw + bx]) continue;
      const int lx = 2 * (bx - 1 + ox) + 1, ly = 2 * (by - 1 + oy) + 1, hx = 2 * bx + 1, hy = 2 * by + 1;
      const std::size_t at[4] = {static_cast<std::size_t>(ly) * w + lx, static_cast<std::size_t>(ly) * w + hx,
                                 static_cast<std::size_t>(hy) * w + lx, static_cast<std::size_t>(hy) * w + hx};
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      // The shaded pixels have odd coordinates and this one does not: none is read after it is written.
      for (int c = 0; c < 3; ++c) {
        out.car.rgb[3 * i + c] = 0.25f * (out.car.rgb[3 * at[0] + c] + out.car.rgb[3 * at[1] + c] +
                                          out.car.rgb[3 * at[2] + c] + out.car.rgb[3 * at[3] + c]);
        out.shadow.rgb[3 * i + c] = 0.25f * (out.shadow.rgb[3 * at[0] + c] + out.shadow.rgb[3 * at[1] + c] +
                                             out.shadow.rgb[3 * at[2] + c] + out.shadow.rgb[3 * at[3] + c]);
      }
      out.car_alpha[i] =
          0.25f * (out.car_alpha[at[0]] + out.car_alpha[at[1]] + out.car_alpha[at[2]] + out.car_alpha[at[3]]);
      out.ground_mask[i] =
          0.25f * (out.ground_mask[at[0]] + out.ground_mask[at[1]] + out.ground_mask[at[2]] + out.ground_mask[at[3]]);
    }
}

}  // namespace odvr::render::detail
