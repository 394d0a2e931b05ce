#version 450
#extension GL_GOOGLE_include_directive : require
// The shading stage of TripleProductRenderer (engine/render/triple_product_renderer.h derives
// the estimator): per car pixel, Σ over BRDF lobes × visibility cones × the lighting SGs that
// the overlap bins list for the lobe, of the triple-product integral; one extra cone per peak.
// Per ground pixel (shadow catcher) the ratio of the Lambertian ground's shadowed lighting to
// its unshadowed lighting. The CPU reference (triple_product_reference.cpp) is the same loop in
// double.
#include "sg_integral.glsl"
#include "cone_trace.glsl"
#include "brdf_lobes.glsl"

// SHADE_LANES (RenderOptions::shade_lanes, 1, 2 or 4) invocations per pixel along z: lane l shades
// the pixel's lobes l, l + L, …, and lane 0 sums the lanes' radiance, peak integrals and counts
// from shared memory. They pay only where too few pixels fill the GPU (H200: 320×180, 4 lanes
// 7.4 ms against 12.4; 1280×720, 35.7 against 27.0: docs/benchmarks/h200.md, third run).
#ifndef SHADE_LANES
#define SHADE_LANES 1
#endif
layout(local_size_x = 8, local_size_y = 8, local_size_z = SHADE_LANES) in;

layout(rgba32f, binding = 0) readonly uniform image2D uGPosition;  // xyz, material index + 1 (0: empty)
layout(rgba32f, binding = 1) readonly uniform image2D uGNormal;    // xyz, roughness
layout(rgba32f, binding = 2) readonly uniform image2D uGBase;      // rgb, metallic
layout(rgba32f, binding = 3) writeonly uniform image2D uCarLayer;  // rgb radiance, coverage
layout(rgba32f, binding = 4) writeonly uniform image2D uShadowLayer;  // rgb ratio, 1 on ground pixels
layout(rgba32f, binding = 5) readonly uniform image2D uGEmission;  // rgb: the radiance the surface emits

struct LightSg {
  vec4 axis_lambda;  // world axis, λ
  vec4 amplitude;    // rgb
};
layout(std430, binding = 0) readonly buffer Srbfs { LightSg srbfs[]; };  // by global SRBF index
layout(std430, binding = 1) readonly buffer Peaks { LightSg peaks[]; };
layout(std430, binding = 2) readonly buffer BinLevels { vec4 binLevels[]; };  // λ_b, n, first begin entry
layout(std430, binding = 3) readonly buffer BinBegin { int binBegin[]; };    // absolute offsets into binSrbfs
layout(std430, binding = 4) readonly buffer BinSrbfs { int binSrbfs[]; };
struct MaterialTerm {
  ivec4 type;
  vec4 color;
  vec4 params;
};
// Per material uTermsPerMaterial BRDF terms (what it emits is in the G-buffer).
layout(std430, binding = 5) readonly buffer Materials { MaterialTerm terms[]; };
layout(std430, binding = 6) writeonly buffer Counts { uvec4 counts[]; };  // lobes, cones, triple products, SGs
// material::ClampedCosineTable over (λ, z = n·c), row-major, its two blocks interleaved:
// ∫ G max(0, n·w) / ∫ G, and the same with FL = (1 − n·w)⁵.
layout(std430, binding = 8) readonly buffer CosineTable { vec2 cosineTable[]; };

uniform ivec2 uSize;
// RenderOptions::supersample with supersample_contrast > 0: a first pass shades one sample per
// pixel (stride k, phase k/2: the sample nearest its centre), a second (uAdaptivePass) the
// other k² − 1 samples of each pixel render_flag.comp listed, invocation i taking sample
// i mod (k² − 1) of list entry i / (k² − 1) (i = y · uListPitch + x), so that every invocation
// that runs shades; render_list_args.comp sizes its dispatch from the list's count on the GPU.
// Otherwise stride 1, phase 0: every sample.
uniform int uSampleStride;
uniform int uSamplePhase;
uniform int uAdaptivePass;
uniform int uFactor;      // k
uniform int uOutWidth;    // the output's width
uniform int uListPitch;   // invocations per row of the second pass
layout(std430, binding = 10) readonly buffer FlaggedList {
  uint flaggedCount;
  uint flagged[];
};
uniform vec3 uCameraPosition;
uniform mat3 uWorldFromCamera;  // columns: camera x (right), y (down), z (forward)
uniform float uFocal;           // pixels
uniform mat3 uEnvFromWorld;     // the overlap bins live in the lighting's own frame
uniform vec3 uConstant;
uniform vec3 uAmbientBounce;  // RenderOptions::ambient_bounce: the lighting's mean radiance L̄; 0: off
uniform int uPeakCount;
uniform int uPeakCones;  // 1: each peak its own cone; 0: peaks shadowed by the lobes' cones
uniform int uBinLevelCount;
uniform float uLevelLambda[6];  // sphere::Healpix(s).Lambda() of the levels used, 3e38 beyond
uniform float uMinRetention;    // RenderOptions::overlap_min_retention
uniform float uSingleConeMaxHalfAngle;
uniform float uConeCoverage;
uniform float uMaxConeHalfAngle;
uniform int uTermsPerMaterial;
uniform int uMaterialCount;
int materialRow(int material) { return material * uTermsPerMaterial; }
uniform float uSurfaceOffset;  // metres along the normal where the car's cones start
// RenderOptions::exact_peak_shadows: each peak's visibility from rays against the triangles (one,
// or seven for a peak wider than 1°; from the surface point gSurface, uExactRayOffset along
// gNormal) instead of its cone.
uniform int uExactTriangles;  // 0: the peaks' cones
uniform float uExactRayOffset;
// RenderOptions::specular_bounce (0: off): the G-buffer march's step, length and surface thickness
// (metres), and how many SRBFs (levels 0–1, by global index) light the surface it hits.
uniform int uBounce;
uniform float uBounceStep;
uniform int uBounceSteps;
uniform float uBounceThickness;
uniform int uBounceSrbfs;
#define BVH_BINDING 14  // 13: render_list_args.comp's
#include "triangle_bvh.glsl"
// GpuModel::bvh_shading: per material kBvhShadingRowsPerMaterial rows, then per BVH triangle its
// vertices' normals (w: its material) from row uBvhShadingMaterials.
layout(std430, binding = 16) readonly buffer BvhShading { vec4 bvhShading[]; };
const int kBvhShadingRowsPerMaterial = 2;  // GpuModel::kBvhShadingRowsPerMaterial
uniform int uBvhShadingMaterials;
vec3 gSurface, gNormal;
const float kPeakRingMinHalfAngle = 0.017453292;  // detail::kPeakRingMinHalfAngle, kPeakRingScale
const float kPeakRingScale = 1.3;
uniform int uGround;
uniform vec2 uGroundCenter;  // xz
uniform float uGroundHalfSize;
uniform int uGroundShadowsBounce;  // RenderOptions::ground_shadows_bounce
uniform float uGroundLitHalfAngle;
uniform vec3 uGroundRadiance;  // detail::PreparedLighting::GroundRadiance

// The ground's lobe is the same clamped cosine about +y at every ground pixel, and so are its
// cones' axes and every lighting SG's weights over them: only the cones' visibilities differ.
// Its shadowed lighting Σ_j a_j ∫P_j Σ_i v_i w_ij / Σ_i w_ij is therefore Σ_i v_i C_i with
// C_i = Σ_j a_j ∫P_j w_ij / Σ_i w_ij, which a pass of one group (uGroundTablePass) computes
// once per render: entries 0 … kMaxCones − 1 C_i, kMaxCones the unshadowed Σ_j a_j ∫P_j, then
// per peak with its own cone a_k ∫P_k. A ground pixel then costs its cones, not cones × SGs.
layout(std430, binding = 11) buffer GroundTable { vec4 groundTable[]; };
uniform int uGroundTablePass;  // 1: this table; 2: the ground's lit-fraction grid (below)

uniform int uGroundPeakCount;
uniform vec4 uGroundPeakAxis[8];  // axis, cone half-angle
uniform float uGroundPeakShare[8];

float peakRaysVisibility(vec3 o, int k);

// detail::GroundLitFraction: the ground's lit fraction at q for its broad light (one cone up) and
// each traced peak (its own cone, or its rays with uExactTriangles), weighted by their shares of
// the ground's irradiance.
float groundLitFraction(vec3 q) {
  float rest = 1.0, lit = 0.0;
  for (int k = 0; k < 8; ++k) {
    if (k >= uGroundPeakCount || uGroundPeakShare[k] <= 0.0) continue;
    lit += uGroundPeakShare[k] * (uExactTriangles > 0
                                      ? peakRaysVisibility(q + vec3(0.0, uExactRayOffset, 0.0), k)
                                      : traceCone(q, uGroundPeakAxis[k].xyz, uGroundPeakAxis[k].w));
    rest -= uGroundPeakShare[k];
  }
  return lit + max(rest, 0.0) * traceCone(q, vec3(0, 1, 0), uGroundLitHalfAngle);
}

// RenderOptions::ground_lit_map_texels: groundLitFraction at the texel centres of a grid over the
// ground (detail::GroundLitMapLayout), written by the pass uGroundTablePass == 2 before the
// shading reads it; uGroundLitMapSize.x == 0: no grid, every cone traces from its ground point.
layout(std430, binding = 12) buffer GroundLitMap { float groundLitMap[]; };
uniform ivec2 uGroundLitMapSize;
uniform vec2 uGroundLitMapOrigin;  // xz of texel (0, 0)'s centre
uniform float uGroundLitMapSpacing;

// detail::SampleGroundLitMap: bilinear between texel centres, 1 outside the grid.
float groundLitMapAt(vec2 xz) {
  vec2 f = (xz - uGroundLitMapOrigin) / uGroundLitMapSpacing;
  if (!(f.x >= 0.0 && f.y >= 0.0 && f.x < float(uGroundLitMapSize.x - 1) && f.y < float(uGroundLitMapSize.y - 1)))
    return 1.0;
  ivec2 i = ivec2(f);
  vec2 t = f - vec2(i);
  int e = i.y * uGroundLitMapSize.x + i.x;
  return mix(mix(groundLitMap[e], groundLitMap[e + 1], t.x),
             mix(groundLitMap[e + uGroundLitMapSize.x], groundLitMap[e + uGroundLitMapSize.x + 1], t.x), t.y);
}

// RenderOptions::ground_shadows_bounce: light from below the horizon stands for the ground's
// bounce, which is darker where the car shadows the ground. A cone from p along dir meets the
// ground at q; the lit fraction there is one cone straight up from q (and the traced peaks'),
// read from the grid when there is one.
float groundLit(vec3 p, vec3 dir) {
  if (uGroundShadowsBounce == 0 || dir.y >= 0.0 || p.y <= 0.0) return 1.0;
  vec3 q = p - (p.y / dir.y) * dir;
  if (abs(q.x - uGroundCenter.x) > uGroundHalfSize || abs(q.z - uGroundCenter.y) > uGroundHalfSize) return 1.0;
  if (uGroundLitMapSize.x > 0) return groundLitMapAt(q.xz);
  return groundLitFraction(vec3(q.x, 0.0, q.z));
}

// material::ClampedCosineMean: the clamped cosine's mean under a unit SG of sharpness λ whose
// axis is at cos θ = z from n, interpolated in the table up to kCosineLambdaMax, the narrow
// Gaussian's closed form beyond (brdf.h derives both).
const int kCosineZ = 129;          // material::kClampedCosineZ
const int kCosineRows = 33;        // material::kClampedCosineRows
const float kCosineLambdaMax = 64.0;
const float kCosineKappa = 8.0;

// erfc for x ≥ 0 (Abramowitz & Stegun 7.1.26, |error| < 1.5·10⁻⁷).
float erfcPositive(float x) {
  float t = 1.0 / (1.0 + 0.3275911 * x);
  return t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429)))) *
         exp(-x * x);
}

// .x: material::ClampedCosineMean, .y: material::ClampedCosineGrazingMean.
vec2 clampedCosineMeans(float z, float lambda) {
  z = clamp(z, -1.0, 1.0);
  lambda = max(lambda, 0.0);
  if (lambda >= kCosineLambdaMax) {
    float k = sqrt(lambda), x = z * k;
    float e = 0.5 * erfcPositive(abs(x) * 0.70710678);
    float cdf = x >= 0.0 ? 1.0 - e : e;
    float pdf = 0.39894228 * exp(-0.5 * x * x);
    float mc = 1.0 / tanh(lambda) - 1.0 / lambda;
    float mean = mc * (z * cdf + pdf / k);
    // The grazing mean from the truncated moments of n·w (material::ClampedCosineGrazingMean).
    float m = z * mc, s2 = (1.0 - z * z) / lambda + 1.0 / (lambda * lambda), s = sqrt(s2);
    float xs = m / s;
    float es = 0.5 * erfcPositive(abs(xs) * 0.70710678);
    float m0 = xs >= 0.0 ? 1.0 - es : es;
    float m1 = m * m0 + s * 0.39894228 * exp(-0.5 * xs * xs);
    float m2 = m * m1 + s2 * m0;
    float m3 = m * m2 + 2.0 * s2 * m1;
    float m4 = m * m3 + 3.0 * s2 * m2;
    float m5 = m * m4 + 4.0 * s2 * m3;
    float m6 = m * m5 + 5.0 * s2 * m4;
    return vec2(mean, max(m1 - 5.0 * m2 + 10.0 * m3 - 10.0 * m4 + 5.0 * m5 - m6, 0.0));
  }
  float row = lambda / (lambda + kCosineKappa) / (kCosineLambdaMax / (kCosineLambdaMax + kCosineKappa)) *
              float(kCosineRows - 1);
  int r = min(int(row), kCosineRows - 2);
  float col = (z + 1.0) * 0.5 * float(kCosineZ - 1);
  int c = clamp(int(col), 0, kCosineZ - 2);
  float fr = row - float(r), fc = col - float(c);
  int i = r * kCosineZ + c;
  return mix(mix(cosineTable[i], cosineTable[i + 1], fc), mix(cosineTable[i + kCosineZ], cosineTable[i + kCosineZ + 1], fc),
             fr);
}

float clampedCosineMean(float z, float lambda) { return clampedCosineMeans(z, lambda).x; }

// ∫ max(0, n·w) G(w) for a unit SG (material::ClampedCosineIntegral).
float clampedCosineIntegral(vec3 n, vec3 axis, float lambda) {
  return clampedCosineMean(dot(n, axis), lambda) * sgIntegral(lambda);
}

// Compile-time bounds, so that every loop over cones and peaks unrolls and their arrays stay in
// registers: indexed by a loop variable, an array becomes a chain of selects on llvmpipe (70x
// slower, measured). The renderer compiles one variant per ring count.
#ifndef CONE_RINGS
#define CONE_RINGS 1
#endif
const int kMaxCones = 1 + 3 * CONE_RINGS * (CONE_RINGS + 1);
const int kMaxPeaks = 8;  // TripleProductRenderer::kMaxPeakCones; fainter peaks use the lobes' cones
const float kTwoPi = 6.28318530717958647692;

float halfValueAngle(float lambda) {
  // e^{λ(cos α − 1)} = 1/2; below λ = ln 2 / 2 the SG never falls to 1/2: α = π.
  return lambda > 0.34657359 ? acos(clamp(1.0 + log(0.5) / lambda, -1.0, 1.0)) : kSgPi;
}

float lambdaForHalfValueAngle(float alpha) { return log(0.5) / (cos(alpha) - 1.0); }

float capHalfAngleHolding(float lambda, float fraction) {
  if (lambda < 1e-3) return acos(1.0 - 2.0 * fraction);
  float c = 1.0 + log(1.0 + fraction * (exp(-2.0 * lambda) - 1.0)) / lambda;
  return acos(clamp(c, -1.0, 1.0));
}

// The cones of one lobe, as visibility::ConesForLobe packs them (its weights are not needed:
// the estimator below weights each cone per lighting SG).
struct ConeSet {
  vec3 axis[kMaxCones];
  float visibility[kMaxCones];
  float ground_lit[kMaxCones];  // groundLit along each cone: 1 but where it meets the shadowed ground
  int count;
  float lambda;  // of every cone's SG (eq. 4.12)
  bool all_visible;
  bool ground_shadowed;  // some cone meets the ground where the car shadows it
  // Clamped-cosine lobes: ∫ max(0, n·w) V_i / ∫ G_cos V_i per cone (coneCosineRatios), so that
  // the visible share weights the cones by the cosine itself; 1 for every other lobe.
  float cosine_ratio[kMaxCones];
};

// The cones' axes, their SG's λ and half-angle, without tracing them.
float lobeConeAxes(vec3 axis, float lambda, inout ConeSet set) {
  float half_value = halfValueAngle(lambda);
  if (half_value <= uSingleConeMaxHalfAngle || CONE_RINGS == 0) {
    float a = min(half_value, uMaxConeHalfAngle);
    set.count = 1;
    set.axis[0] = axis;
    set.lambda = lambdaForHalfValueAngle(a);
    return a;
  }
  float cap = capHalfAngleHolding(lambda, uConeCoverage);
  float beta = min(cap / float(2 * CONE_RINGS + 1), uMaxConeHalfAngle);
  vec3 helper = abs(axis.z) < 0.9 ? vec3(0, 0, 1) : vec3(1, 0, 0);
  vec3 e1 = normalize(cross(helper, axis)), e2 = cross(axis, e1);
  // Ring r's cones start at 1 + 3r(r − 1): indices the compiler knows once the loops unroll,
  // where a running count made the array dynamically indexed (local memory on a GPU).
  set.count = kMaxCones;
  set.axis[0] = axis;
  for (int r = 1; r <= CONE_RINGS; ++r) {
    float theta = min(2.0 * float(r) * beta, kSgPi);
    float phase = (r % 2 == 0) ? kSgPi / float(6 * r) : 0.0;
    for (int k = 0; k < 6 * r; ++k) {
      float phi = phase + kTwoPi * float(k) / float(6 * r);
      set.axis[1 + 3 * r * (r - 1) + k] = normalize(cos(theta) * axis + sin(theta) * (cos(phi) * e1 + sin(phi) * e2));
    }
  }
  set.lambda = lambdaForHalfValueAngle(beta);
  return beta;
}

void traceLobeCones(vec3 axis, float lambda, vec3 p, inout ConeSet set) {
  float half_angle = lobeConeAxes(axis, lambda, set);
  if (set.count == 1) {
    set.visibility[0] = traceCone(p, axis, half_angle);
    set.ground_lit[0] = groundLit(p, axis);
  } else {
    for (int i = 0; i < kMaxCones; ++i) {
      set.visibility[i] = traceCone(p, set.axis[i], half_angle);
      set.ground_lit[i] = groundLit(p, set.axis[i]);
    }
  }
  set.all_visible = true;
  set.ground_shadowed = false;
  for (int i = 0; i < kMaxCones; ++i)
    if (i < set.count) {
      set.all_visible = set.all_visible && set.visibility[i] >= 1.0;
      set.ground_shadowed = set.ground_shadowed || set.ground_lit[i] < 1.0;
    }
}

// The triple_product_reference.cpp ConeCosineRatios: the SG stand-in of the cosine is 17 % high
// at the normal and half the cosine's value at 80°, so its products alone would weight the
// cones wrongly.
void coneCosineRatios(vec3 n, bool cosine, inout ConeSet set) {
  for (int i = 0; i < kMaxCones; ++i) {
    set.cosine_ratio[i] = 1.0;
    if (!cosine || i >= set.count) continue;
    float sg = sgIntegral2(n, kCosineSgLambda, set.axis[i], set.lambda);
    set.cosine_ratio[i] = sg > 0.0 ? clampedCosineIntegral(n, set.axis[i], set.lambda) / sg : 0.0;
  }
}

// The visible share of ∫ G_lobe G_light over the cones: Σ v_i ∫P V_i / Σ ∫P V_i with
// P = G_lobe G_light and V_i the cone SGs, the exponents shifted by their maximum so that sharp
// products far from every cone do not underflow to 0/0.
// ground_loss: instead Σ v_i (1 − g_i) ∫P V_i / Σ ∫P V_i, g_i the cones' ground_lit: the share of
// the product that the car's shadow takes off the ground's bounce.
// Per cone only λ and the log amplitude of P·V_i are needed, both from c = a·c_i:
// r² = λp² + λc² + 2λpλc c and r − Λ = −λpλc |a − c_i|² / (r + Λ) with |a − c_i|² = 2(1 − c)
// (sg_integral.glsl), one dot product where sgProduct builds two vectors; and the maximum is
// taken first, where an online rescale spent an exp on every new maximum. A lobe of one cone
// shares its visibility whatever the weights.
float visibleShareOf(SgProduct prod, in ConeSet set, bool ground_loss) {
  if (set.count == 1) return ground_loss ? set.visibility[0] * (1.0 - set.ground_lit[0]) : set.visibility[0];
  float lp = prod.lambda, lc = set.lambda, sum = lp + lc, twice = 2.0 * lp * lc;
  float log_w[kMaxCones], shape[kMaxCones];
  float top = -3.0e38;
  for (int i = 0; i < kMaxCones; ++i) {
    float gap = 1.0 - dot(prod.axis, set.axis[i]);  // |a − c_i|² / 2
    float r = sqrt(max(sum * sum - twice * gap, 0.0));
    log_w[i] = -twice * gap / (r + sum);
    shape[i] = sgShape(r) * set.cosine_ratio[i];
    if (i < set.count) top = max(top, log_w[i]);
  }
  float num = 0.0, den = 0.0;
  for (int i = 0; i < kMaxCones; ++i) {
    if (i >= set.count) continue;
    float w = exp(log_w[i] - top) * shape[i];
    num += w * set.visibility[i] * (ground_loss ? 1.0 - set.ground_lit[i] : 1.0);
    den += w;
  }
  if (den > 0.0) return num / den;
  return ground_loss ? set.visibility[0] * (1.0 - set.ground_lit[0]) : set.visibility[0];
}

float visibleShare(SgProduct prod, in ConeSet set) { return visibleShareOf(prod, set, false); }

int binLevelFor(float lambda) {
  int k = 0;
  while (k + 1 < uBinLevelCount && binLevels[k + 1].x <= lambda) ++k;
  return k;
}

ivec2 overlapRange(vec3 axis_world, float lambda) {
  if (uBinLevelCount == 0) return ivec2(0, 0);
  vec4 level = binLevels[binLevelFor(lambda)];
  vec3 d = normalize(uEnvFromWorld * axis_world);
  int n = int(level.y);
  float theta = acos(clamp(d.y, -1.0, 1.0));
  float phi = atan(-d.z, d.x);
  if (phi < 0.0) phi += kTwoPi;
  int t = clamp(int(floor(theta * float(n) / kSgPi + 0.5)), 0, n);
  int p = int(floor(phi * float(n) / kSgPi + 0.5)) % (2 * n);
  int b = int(level.z) + t * 2 * n + p;
  return ivec2(binBegin[b], binBegin[b + 1]);
}

// The linear factor (1 + ℓ·wi) of the lobe being shaded (material::Lobe::linear; 0 but for the
// principled diffuse's retro-reflection), integrated against a product SG: an SG's mean direction
// is its axis times coth λ − 1/λ (material::LinearFactor).
vec3 gLinear;
bool gCosine;  // the lobe being shaded is a clamped cosine around gCosineNormal
vec3 gCosineNormal;

float linearFactor(SgProduct p) {
  if (gLinear == vec3(0.0)) return 1.0;
  float m = p.lambda < 1e-3 ? p.lambda / 3.0 : 1.0 / tanh(p.lambda) - 1.0 / p.lambda;
  return 1.0 + dot(gLinear, p.axis) * m;
}

vec3 gGrazing;  // and its grazing factor (material::Lobe::grazing) of x = gView·wi
vec3 gView;

// material::ClampedCosineLobeIntegral against a unit light SG; p: the lobe's SG stand-in times it.
float clampedCosineLobeIntegral(vec3 axis, float lambda, SgProduct p) {
  vec2 m = clampedCosineMeans(dot(gCosineNormal, axis), lambda);
  if (gLinear == vec3(0.0) && gGrazing == vec3(0.0)) return m.x * sgIntegral(lambda);
  vec3 mean_direction = p.axis * (p.lambda < 1e-3 ? p.lambda / 3.0 : 1.0 / tanh(p.lambda) - 1.0 / p.lambda);
  float x = dot(gView, mean_direction);
  return (m.x * (1.0 + dot(gLinear, mean_direction)) + m.y * (gGrazing.x + x * (gGrazing.y + x * gGrazing.z))) *
         sgIntegral(lambda);
}

// ≥ 0: the visible share of the whole lobe, used for every lighting SG (a GGX tail, see
// emitLobe); < 0: each SG's own.
float gLobeShare;

// One lighting SG's contribution to a lobe: unshadowed ∫ G_lobe G_light (unit amplitudes) times
// the visible share.
void addLight(vec3 lobe_axis, float lobe_lambda, vec3 axis, float lambda, vec3 amplitude, in ConeSet set,
              inout vec3 shaded, inout vec3 unshadowed, inout uvec4 count) {
  SgProduct prod = sgProduct(lobe_axis, lobe_lambda, axis, lambda);
  float full = gCosine ? clampedCosineLobeIntegral(axis, lambda, prod)
                       : kTwoPi * exp(prod.log_amplitude) * sgShape(prod.lambda) * linearFactor(prod);
  float share = 1.0;
  if (!set.all_visible && gLobeShare >= 0.0) {
    share = gLobeShare;
  } else if (!set.all_visible) {
    share = visibleShare(prod, set);
    count.z += uint(set.count);
  }
  shaded += amplitude * (full * share);
  unshadowed += amplitude * full;
  count.w += 1u;
}

// lighting::OverlapBins::MaxLevel(λ, share).
int maxLevelFor(float lambda, float share) {
  int depth = 0;
  for (int s = 1; s < 6; ++s)
    if (share * lambda >= uMinRetention * (uLevelLambda[s] + lambda)) depth = s;
  return depth;
}

// Σ over the lobe's lighting SGs: the constant, the overlapping SRBFs, and the peaks when they
// have no cone of their own. A GGX tail (tail_share > 0, material::Lobe::tail_share), and with
// uLobeDepth every lobe, stops at the deepest level it needs (the lists are sorted by global
// index, so by level; a bin's list goes as deep as the sharpest lobe it serves).
uniform int uLobeDepth;  // RenderOptions::depth_per_lobe
void shadeLobe(vec3 lobe_axis, float lobe_lambda, float tail_share, in ConeSet set, inout vec3 shaded,
               inout vec3 unshadowed, inout uvec4 count) {
  if (uConstant != vec3(0.0))
    addLight(lobe_axis, lobe_lambda, vec3(0, 1, 0), 0.0, uConstant, set, shaded, unshadowed, count);
  // lighting::GlobalSrbfIndex(d + 1, 0): the first SRBF below the lobe's deepest level d.
  int end = tail_share > 0.0 || uLobeDepth != 0
                ? 4 * ((1 << (2 * (maxLevelFor(lobe_lambda, tail_share > 0.0 ? tail_share : 1.0) + 1))) - 1)
                : 0x7fffffff;
  ivec2 range = overlapRange(lobe_axis, lobe_lambda);
  // Software-pipelined: entry k + 1's SG and entry k + 2's index are fetched before entry k is
  // used, so that the dependent loads overlap the arithmetic instead of stalling it.
  int k = range.x;
  int index = k < range.y ? binSrbfs[k] : end;
  int index_next = k + 1 < range.y ? binSrbfs[k + 1] : end;
  LightSg next;
  if (index < end) next = srbfs[index];
  while (index < end) {
    LightSg g = next;
    int index_after = k + 2 < range.y ? binSrbfs[k + 2] : end;
    if (index_next < end) next = srbfs[index_next];
    if (g.amplitude.xyz != vec3(0.0))
      addLight(lobe_axis, lobe_lambda, g.axis_lambda.xyz, g.axis_lambda.w, g.amplitude.xyz, set, shaded, unshadowed,
               count);
    index = index_next;
    index_next = index_after;
    ++k;
  }
  for (int k = uPeakCones != 0 ? kMaxPeaks : 0; k < uPeakCount; ++k)
      addLight(lobe_axis, lobe_lambda, peaks[k].axis_lambda.xyz, peaks[k].axis_lambda.w, peaks[k].amplitude.xyz, set,
               shaded, unshadowed, count);
}

// Peaks with their own cones: Σ_p μ_p ∫ G_lobe G_p · v_p (the clamped cosine exactly).
float peakIntegral(vec3 lobe_axis, float lobe_lambda, bool cosine, vec3 axis, float lambda) {
  SgProduct p = sgProduct(lobe_axis, lobe_lambda, axis, lambda);
  return cosine ? clampedCosineLobeIntegral(axis, lambda, p)
                : kTwoPi * exp(p.log_amplitude) * sgShape(p.lambda) * linearFactor(p);
}

void shadePeaks(vec3 lobe_axis, float lobe_lambda, bool cosine, in float peak_visibility[kMaxPeaks],
                inout vec3 shaded, inout vec3 unshadowed) {
  if (uPeakCones == 0) return;
  for (int k = 0; k < kMaxPeaks; ++k) {
    if (k >= uPeakCount) continue;
    float full = peakIntegral(lobe_axis, lobe_lambda, cosine, peaks[k].axis_lambda.xyz, peaks[k].axis_lambda.w);
    shaded += peaks[k].amplitude.xyz * (full * peak_visibility[k]);
    unshadowed += peaks[k].amplitude.xyz * full;
  }
}

// Peak k's visibility from o by rays against the triangles (detail::PeakRayDirections: the axis,
// and for a peak wider than 1° six rays around it).
float peakRaysVisibility(vec3 o, int k) {
  vec3 axis = peaks[k].axis_lambda.xyz;
  float a = halfValueAngle(peaks[k].axis_lambda.w);
  float lit = rayOccluded(o, axis) ? 0.0 : 1.0;
  if (a < kPeakRingMinHalfAngle) return lit;
  vec3 helper = abs(axis.y) < 0.9 ? vec3(0, 1, 0) : vec3(1, 0, 0);
  vec3 e1 = normalize(cross(helper, axis)), e2 = cross(axis, e1);
  float r = min(kPeakRingScale * a, uMaxConeHalfAngle);
  for (int j = 0; j < 6; ++j) {
    float phi = kTwoPi * float(j) / 6.0;
    lit += rayOccluded(o, normalize(cos(r) * axis + sin(r) * (cos(phi) * e1 + sin(phi) * e2))) ? 0.0 : 1.0;
  }
  return lit / 7.0;
}

// Peak k's visibility from a surface point: its rays from `surface` (uExactTriangles), or its cone
// from `p`, the cones' origin off the surface.
float peakVisibility(vec3 p, vec3 surface, vec3 n, int k) {
  if (uExactTriangles > 0) return peakRaysVisibility(surface + uExactRayOffset * n, k);
  return traceCone(p, peaks[k].axis_lambda.xyz, min(halfValueAngle(peaks[k].axis_lambda.w), uMaxConeHalfAngle));
}

void tracePeakCones(vec3 p, out float peak_visibility[kMaxPeaks], inout uvec4 count) {
  for (int k = 0; k < kMaxPeaks; ++k) peak_visibility[k] = 1.0;
  if (uPeakCones == 0) return;
  for (int k = 0; k < kMaxPeaks; ++k) {
    if (k >= uPeakCount) continue;
    peak_visibility[k] = peakVisibility(p, gSurface, gNormal, k);
    count.y += 1u;
  }
}

// RenderOptions::specular_bounce, per material term (TripleProductRenderer::kTermsPerMaterial):
// Σ over its specular lobes (GGX tails included) of weight · ∫ lobe · (1 − visible share), and
// their axes weighted by that (luminance): the light the term's cones lose to the car, and where
// it comes from.
const int kBounceTerms = 2;
int gTerm;
vec3 gBounceWeight[kBounceTerms];
vec3 gBounceAxis[kBounceTerms];

// The pixel being shaded, for emitLobe.
vec3 gOrigin;
vec3 gRadiance;
uvec4 gCount;
float gPeakVisibility[kMaxPeaks];
// Per traced peak, Σ over the lobes of ∫ lobe × peak plus what the GGX lobes leave out under it
// (material::GgxResidualUnderSgLight); added once per pixel, clamped at 0 and
// shadowed by the peak's cone (triple_product_reference.cpp does the same).
vec3 gPeakSum[kMaxPeaks];
ConeSet gSet;

void emitLobe(vec3 axis, float lambda, float tail_share, vec3 weight, bool cosine) {
  traceLobeCones(axis, lambda, gOrigin, gSet);
  gCosine = cosine;
  gCosineNormal = axis;
  coneCosineRatios(axis, cosine, gSet);
  vec3 shaded = vec3(0.0), unshadowed = vec3(0.0);
  // A GGX tail is seen through one visible share, the lobe's own (its cones weighted by the
  // lobe alone), not one per lighting SG: the tail is smooth, the sharp lights (peaks) have their
  // own cones, and per-SG shares were the tail's largest cost (same errors, bench render).
  gLobeShare = -1.0;
  if (tail_share > 0.0 && !gSet.all_visible) {
    SgProduct q;
    q.axis = axis;
    q.lambda = lambda;
    q.log_amplitude = 0.0;
    gLobeShare = visibleShare(q, gSet);
    gCount.z += uint(gSet.count);
  }
  shadeLobe(axis, lambda, tail_share, gSet, shaded, unshadowed, gCount);
  if (gSet.ground_shadowed) {
    // The lighting's radiance below the horizon stands for the ground's bounce, unshadowed; what
    // the car's shadow takes off it is the ground's own radiance over the cones that meet the
    // shadow, whatever SGs carry the lighting across the horizon (triple_product_renderer.h).
    SgProduct q = sgProduct(axis, lambda, vec3(0, 1, 0), 0.0);
    float full = gCosine ? clampedCosineLobeIntegral(vec3(0, 1, 0), 0.0, q)
                         : kTwoPi * exp(q.log_amplitude) * sgShape(q.lambda) * linearFactor(q);
    // Never below 0: a lobe cannot lose more light than it has.
    shaded -= min(uGroundRadiance * (full * visibleShareOf(q, gSet, true)), max(shaded, vec3(0.0)));
    gCount.z += uint(gSet.count);
  }
  gRadiance += weight * shaded;
  if (cosine && uAmbientBounce != vec3(0.0) && !gSet.all_visible) {
    // RenderOptions::ambient_bounce: the occluded part of the lobe under a constant light sees
    // car surfaces that send a v L̄ / (1 − a (1 − v)), a = π · weight, v the visible share.
    SgProduct q = sgProduct(axis, lambda, vec3(0, 1, 0), 0.0);
    float v = visibleShare(q, gSet);
    vec3 a = min(kLobePi * weight, vec3(1.0));
    vec3 occluder = a * v * uAmbientBounce / max(vec3(1.0) - a * (1.0 - v), vec3(1e-4));
    gRadiance += weight * occluder * (clampedCosineLobeIntegral(vec3(0, 1, 0), 0.0, q) * (1.0 - v));
    gCount.z += uint(gSet.count);
  }
  if (uBounce != 0 && !cosine && !gSet.all_visible) {
    // A GGX tail's loss too: the tail is the lobe's wide part, the one that meets the car most,
    // and the light it loses there is the car's as much as the peak's is. Its visible share was
    // traced above (gLobeShare); a peak lobe's is traced here.
    float visible = gLobeShare;
    if (visible < 0.0) {
      SgProduct q;
      q.axis = axis;
      q.lambda = lambda;
      q.log_amplitude = 0.0;
      visible = visibleShare(q, gSet);
      gCount.z += uint(gSet.count);
    }
    vec3 lost = weight * (sgIntegral(lambda) * (1.0 - visible));
    gBounceWeight[gTerm] += lost;
    gBounceAxis[gTerm] += axis * dot(lost, vec3(0.2126, 0.7152, 0.0722));
  }
  if (uPeakCones != 0)
    for (int k = 0; k < kMaxPeaks; ++k)
      if (k < uPeakCount)
        gPeakSum[k] += weight * peakIntegral(axis, lambda, cosine, peaks[k].axis_lambda.xyz, peaks[k].axis_lambda.w);
  gCount.x += 1u;
  gCount.y += uint(gSet.count);
}

// Where world point x falls in the G-buffer: −1 off the picture or behind the camera; else its
// pixel q, and 1 with `behind` = how far x lies behind the car surface there along the camera's
// axis, 0 where the pixel shows no car.
int gbufferAt(vec3 x, out ivec2 q, out float behind) {
  q = ivec2(0);
  behind = 0.0;
  vec3 c = transpose(uWorldFromCamera) * (x - uCameraPosition);
  if (!(c.z > 1e-4)) return -1;  // behind the camera (or not a number)
  vec2 f = floor(c.xy / c.z * uFocal + 0.5 * vec2(uSize));
  if (!(f.x >= 0.0 && f.y >= 0.0 && f.x < float(uSize.x) && f.y < float(uSize.y))) return -1;
  q = ivec2(f);
  vec4 gp = imageLoad(uGPosition, q);
  if (gp.w < 0.5) return 0;
  behind = c.z - dot(uWorldFromCamera[2], gp.xyz - uCameraPosition);
  return 1;
}

// The first car surface the G-buffer shows behind the ray o + t d (t = uBounceStep, 2 uBounceStep,
// …), by less than uBounceThickness along the camera's axis; false when the ray leaves the picture
// or the march ends first.
bool bounceHit(vec3 o, vec3 d, out ivec2 hit) {
  for (int s = 1; s <= uBounceSteps; ++s) {
    float behind;
    int at = gbufferAt(o + (uBounceStep * float(s)) * d, hit, behind);
    if (at < 0) return false;
    if (at > 0 && behind > 0.0 && behind < uBounceThickness) return true;
  }
  return false;
}

// The radiance a car surface at p, normal n, of `material` (its glTF base, metallic and roughness
// where the material is the glTF's) sends along wo_in: its specular lobes under the constant, the
// SRBFs below uBounceSrbfs and the peaks (shadowed from there as a pixel's own: rays or cones),
// plus what it emits.
vec3 surfaceBounceRadiance(vec3 p, vec3 n, int material, vec3 base, float metallic, float roughness, vec3 emitted,
                           vec3 wo_in) {
  if (material < 0 || material >= uMaterialCount) return vec3(0.0);
  if (dot(n, wo_in) <= 0.0) return emitted;
  vec3 wo = bendView(n, wo_in);
  float visible[kMaxPeaks];
  for (int k = 0; k < kMaxPeaks; ++k) {
    visible[k] = k < uPeakCount ? peakVisibility(p + uSurfaceOffset * n, p, n, k) : 1.0;
  }
  gLinear = vec3(0.0);  // a specular lobe's integrals have no linear factor
  vec3 radiance = vec3(0.0);
  for (int k = 0; k < uTermsPerMaterial; ++k) {
    MaterialTerm term = terms[materialRow(material) + k];
    TermLobes t = describeTerm(term.type.x, term.color, term.params, base, metallic, roughness, n, wo);
    for (int i = 0; i < t.count; ++i) {
      vec3 axis, weight;
      float lambda;
      bool cosine;
      if (!termLobe(t, i, n, wo, axis, lambda, weight, cosine) || cosine) continue;
      vec3 light = uConstant * peakIntegral(axis, lambda, false, vec3(0, 1, 0), 0.0);
      for (int j = 0; j < uBounceSrbfs; ++j)
        if (srbfs[j].amplitude.xyz != vec3(0.0))
          light += srbfs[j].amplitude.xyz *
                   peakIntegral(axis, lambda, false, srbfs[j].axis_lambda.xyz, srbfs[j].axis_lambda.w);
      for (int j = 0; j < uPeakCount; ++j)
        light += peaks[j].amplitude.xyz * (j < kMaxPeaks ? visible[j] : 1.0) *
                 peakIntegral(axis, lambda, false, peaks[j].axis_lambda.xyz, peaks[j].axis_lambda.w);
      radiance += weight * light;
    }
  }
  return max(radiance, vec3(0.0)) + emitted;
}

// surfaceBounceRadiance of the car surface at G-buffer pixel q.
vec3 bounceRadiance(ivec2 q, vec3 wo_in) {
  vec4 gp = imageLoad(uGPosition, q);
  vec4 gn = imageLoad(uGNormal, q);
  vec4 gb = imageLoad(uGBase, q);
  return surfaceBounceRadiance(gp.xyz, normalize(gn.xyz), int(gp.w + 0.5) - 1, gb.rgb, gb.a, gn.w,
                               imageLoad(uGEmission, q).rgb, wo_in);
}

// The G-buffer pixel that shows world point x (within uBounceThickness along the camera's axis).
bool gbufferShows(vec3 x, out ivec2 q) {
  float behind;
  return gbufferAt(x, q, behind) > 0 && abs(behind) < uBounceThickness;
}

// What the car sends back along −d from the first triangle the ray o + t d hits (the BVH): the
// G-buffer's surface there when the camera sees it (its textures), else the triangle's own — its
// vertices' normals interpolated and turned to face the ray, its material's mean factors
// (GpuModel::bvh_shading). false when the ray leaves the car.
bool triangleBounce(vec3 o, vec3 d, out vec3 radiance) {
  radiance = vec3(0.0);
  int tri;
  float t;
  vec2 uv;
  if (!rayClosestHit(o, d, 3.0e38, tri, t, uv)) return false;
  vec3 x = o + t * d;
  ivec2 q;
  if (gbufferShows(x, q)) {
    radiance = bounceRadiance(q, -d);
    return true;
  }
  int row = uBvhShadingMaterials + 3 * tri;
  vec4 n0 = bvhShading[row], n1 = bvhShading[row + 1], n2 = bvhShading[row + 2];
  vec3 n = (1.0 - uv.x - uv.y) * n0.xyz + uv.x * n1.xyz + uv.y * n2.xyz;
  vec3 v0 = bvhTriangles[3 * tri].xyz;
  vec3 face = cross(bvhTriangles[3 * tri + 1].xyz - v0, bvhTriangles[3 * tri + 2].xyz - v0);
  n = dot(n, n) > 1e-12 ? normalize(n) : normalize(face);
  if (dot(n, d) > 0.0) n = -n;  // both sides shade, as Cycles turns a back face's normal to the ray
  int material = int(n0.w + 0.5);
  vec4 base_metallic = bvhShading[kBvhShadingRowsPerMaterial * material];
  vec4 emission_roughness = bvhShading[kBvhShadingRowsPerMaterial * material + 1];
  radiance = surfaceBounceRadiance(x, n, material, base_metallic.rgb, base_metallic.a, emission_roughness.a,
                                   emission_roughness.rgb, -d);
  return true;
}

// Σ over the terms whose specular lobes lost light to the car: that loss's weight times the
// radiance of the surface the G-buffer shows along their mean direction.
vec3 specularBounce() {
  vec3 sum = vec3(0.0);
  for (int t = 0; t < kBounceTerms; ++t) {
    if (length(gBounceAxis[t]) <= 0.0) continue;
    vec3 d = normalize(gBounceAxis[t]);
    vec3 o = gSurface + uExactRayOffset * gNormal;
    if (uExactTriangles > 0) {
      vec3 radiance;
      if (triangleBounce(o, d, radiance)) sum += gBounceWeight[t] * radiance;
      continue;
    }
    ivec2 q;
    if (bounceHit(o, d, q)) sum += gBounceWeight[t] * bounceRadiance(q, -d);
  }
  return sum;
}

// uGroundTablePass: invocation i < kMaxCones shades the ground's lobe as if cone i alone were
// visible, which yields C_i (and, for i = 0, the unshadowed sum); invocation kMaxCones + 1 + k
// shades the traced peak k alone.
void buildGroundTable() {
  int i = int(gl_LocalInvocationIndex);
  const vec3 up = vec3(0, 1, 0);
  lobeConeAxes(up, kCosineSgLambda, gSet);
  gCosine = true;
  gCosineNormal = up;
  coneCosineRatios(up, true, gSet);
  gSet.all_visible = false;
  gSet.ground_shadowed = false;
  for (int j = 0; j < kMaxCones; ++j) {
    gSet.visibility[j] = j == i ? 1.0 : 0.0;
    gSet.ground_lit[j] = 1.0;
  }
  uvec4 count = uvec4(0);
  vec3 shaded = vec3(0.0), unshadowed = vec3(0.0);
  if (i < kMaxCones) {
    shadeLobe(up, kCosineSgLambda, 0.0, gSet, shaded, unshadowed, count);
    groundTable[i] = vec4(shaded, 0.0);
    if (i == 0) groundTable[kMaxCones] = vec4(unshadowed, 0.0);
  } else if (i > kMaxCones && i <= kMaxCones + kMaxPeaks) {
    float alone[kMaxPeaks];
    for (int k = 0; k < kMaxPeaks; ++k) alone[k] = k == i - kMaxCones - 1 ? 1.0 : 0.0;
    shadePeaks(up, kCosineSgLambda, true, alone, shaded, unshadowed);
    groundTable[i] = vec4(shaded, 0.0);
  }
}

#if SHADE_LANES > 1
// Scalars, not vec3s, which a compiler may pad to four: at 4 lanes this is 31 744 of the 32 768
// bytes a GL 4.5 implementation has to offer.
const int kLaneSlots = 64 * SHADE_LANES;
shared float sRadiance[3 * kLaneSlots];
shared uint sCount[4 * kLaneSlots];
shared float sPeakSum[3 * kMaxPeaks * kLaneSlots];
#endif

void main() {
  int lane = int(gl_LocalInvocationID.z);
  ivec2 pixel = ivec2(gl_GlobalInvocationID.xy) * uSampleStride + uSamplePhase;
  bool shading = true;
  if (uAdaptivePass != 0) {
    int i = int(gl_GlobalInvocationID.y) * uListPitch + int(gl_GlobalInvocationID.x);
    int perPixel = uFactor * uFactor - 1;
    shading = i < int(flaggedCount) * perPixel;
    int sub = i % perPixel;
    if (sub >= (uFactor / 2) * uFactor + uFactor / 2) ++sub;  // the centre sample is shaded already
    int entry = shading ? int(flagged[i / perPixel]) : 0;
    pixel = ivec2(entry % uOutWidth, entry / uOutWidth) * uFactor + ivec2(sub % uFactor, sub / uFactor);
  }
  shading = shading && pixel.x < uSize.x && pixel.y < uSize.y;
  gCount = uvec4(0);
  gLinear = vec3(0.0);
  gGrazing = vec3(0.0);
  gCosine = false;
  gLobeShare = -1.0;
  gCosineNormal = vec3(0.0, 1.0, 0.0);
  gRadiance = vec3(0.0);
  for (int k = 0; k < kMaxPeaks; ++k) gPeakSum[k] = vec3(0.0);
  for (int t = 0; t < kBounceTerms; ++t) {
    gBounceWeight[t] = vec3(0.0);
    gBounceAxis[t] = vec3(0.0);
  }
  if (uGroundTablePass == 1) {  // one group, all of it here: no barrier below is reached
    buildGroundTable();
    return;
  }
  if (uGroundTablePass == 2) {  // a texel per invocation of lane 0; every invocation returns here
    ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
    if (lane == 0 && texel.x < uGroundLitMapSize.x && texel.y < uGroundLitMapSize.y) {
      vec2 xz = uGroundLitMapOrigin + vec2(texel) * uGroundLitMapSpacing;
      groundLitMap[texel.y * uGroundLitMapSize.x + texel.x] = groundLitFraction(vec3(xz.x, 0.0, xz.y));
    }
    return;
  }
  vec4 car = vec4(0.0);
  vec4 shadow = vec4(1.0, 1.0, 1.0, 0.0);
  int material = -1;
  if (shading) {
    vec4 gp = imageLoad(uGPosition, pixel);
    material = int(gp.w + 0.5) - 1;
    if (material >= 0 && material < uMaterialCount) {
      vec4 gn = imageLoad(uGNormal, pixel);
      vec4 gb = imageLoad(uGBase, pixel);
      vec3 p = gp.xyz, n = normalize(gn.xyz);
      vec3 wo = bendView(n, normalize(uCameraPosition - p));
      gOrigin = p + uSurfaceOffset * n;
      gSurface = p;
      gNormal = n;
      if (lane == 0) tracePeakCones(gOrigin, gPeakVisibility, gCount);
      int valid = 0;  // the pixel's lobes so far: lobe j is lane j mod SHADE_LANES's
      for (int k = 0; k < uTermsPerMaterial; ++k) {
        MaterialTerm term = terms[materialRow(material) + k];
        TermLobes t = describeTerm(term.type.x, term.color, term.params, gb.rgb, gb.a, gn.w, n, wo);
        gTerm = min(k, kBounceTerms - 1);
        for (int i = 0; i < t.count; ++i) {
          vec3 axis, weight;
          float lambda;
          bool cosine;
          if (termLobe(t, i, n, wo, axis, lambda, weight, cosine)) {
            if (valid % SHADE_LANES == lane) {
              gLinear = cosine ? t.cosine_linear : vec3(0.0);
              gGrazing = cosine ? t.cosine_grazing : vec3(0.0);
              gView = wo;
              emitLobe(axis, lambda, termLobeTailShare(t, i), weight, cosine);
            }
            ++valid;
          }
        }
        if (uPeakCones != 0 && k % SHADE_LANES == lane)
          for (int j = 0; j < kMaxPeaks; ++j)
            if (j < uPeakCount)
              gPeakSum[j] += ggxResidualUnderLight(t, n, wo, peaks[j].axis_lambda.xyz, peaks[j].axis_lambda.w);
      }
    } else if (uGround != 0 && lane == 0) {
      vec3 dir = normalize(uWorldFromCamera * vec3((vec2(pixel) + 0.5 - 0.5 * vec2(uSize)) / uFocal, 1.0));
      float t = dir.y < 0.0 ? -uCameraPosition.y / dir.y : -1.0;
      vec3 p = uCameraPosition + t * dir;
      if (t > 0.0 && abs(p.x - uGroundCenter.x) <= uGroundHalfSize && abs(p.z - uGroundCenter.y) <= uGroundHalfSize) {
        p.y = 0.0;
        const vec3 up = vec3(0, 1, 0);
        gSurface = p;
        gNormal = up;
        traceLobeCones(up, kCosineSgLambda, p, gSet);
        tracePeakCones(p, gPeakVisibility, gCount);
        gCount.y += uint(gSet.count);
        bool lit = gSet.all_visible;
        for (int k = 0; k < kMaxPeaks; ++k) lit = lit && gPeakVisibility[k] >= 1.0;
        shadow.a = 1.0;
        if (!lit) {
          vec3 shaded = vec3(0.0), unshadowed = groundTable[kMaxCones].rgb;
          for (int i = 0; i < kMaxCones; ++i)
            if (i < gSet.count) shaded += gSet.visibility[i] * groundTable[i].rgb;
          if (uPeakCones != 0)
            for (int k = 0; k < kMaxPeaks; ++k)
              if (k < uPeakCount) {
                shaded += gPeakVisibility[k] * groundTable[kMaxCones + 1 + k].rgb;
                unshadowed += groundTable[kMaxCones + 1 + k].rgb;
              }
          gCount.x += 1u;
          gCount.z += uint(gSet.count);  // one weighted sum over the cones, no SG per pixel
          for (int c = 0; c < 3; ++c) shadow[c] = unshadowed[c] > 0.0 ? clamp(shaded[c] / unshadowed[c], 0.0, 1.0) : 1.0;
        }
      }
    }
  }
#if SHADE_LANES > 1
  // Every invocation of the group reaches the barrier; then lane 0 adds the others' shares.
  int slot = int(gl_LocalInvocationID.y * 8u + gl_LocalInvocationID.x) * SHADE_LANES;
  for (int c = 0; c < 3; ++c) {
    sRadiance[3 * (slot + lane) + c] = gRadiance[c];
    for (int k = 0; k < kMaxPeaks; ++k) sPeakSum[(3 * kMaxPeaks) * (slot + lane) + 3 * k + c] = gPeakSum[k][c];
  }
  for (int c = 0; c < 4; ++c) sCount[4 * (slot + lane) + c] = gCount[c];
  memoryBarrierShared();
  barrier();
  if (lane == 0)
    for (int l = 1; l < SHADE_LANES; ++l) {
      for (int c = 0; c < 3; ++c) {
        gRadiance[c] += sRadiance[3 * (slot + l) + c];
        for (int k = 0; k < kMaxPeaks; ++k) gPeakSum[k][c] += sPeakSum[(3 * kMaxPeaks) * (slot + l) + 3 * k + c];
      }
      for (int c = 0; c < 4; ++c) gCount[c] += sCount[4 * (slot + l) + c];
    }
  if (uBounce != 0) {
    // The bounce's sums in the peaks' slots, once lane 0 has read those (6 of their 3 kMaxPeaks).
    barrier();
    for (int t = 0; t < kBounceTerms; ++t)
      for (int c = 0; c < 3; ++c) {
        sPeakSum[(3 * kMaxPeaks) * (slot + lane) + 6 * t + c] = gBounceWeight[t][c];
        sPeakSum[(3 * kMaxPeaks) * (slot + lane) + 6 * t + 3 + c] = gBounceAxis[t][c];
      }
    memoryBarrierShared();
    barrier();
    if (lane == 0)
      for (int l = 1; l < SHADE_LANES; ++l)
        for (int t = 0; t < kBounceTerms; ++t)
          for (int c = 0; c < 3; ++c) {
            gBounceWeight[t][c] += sPeakSum[(3 * kMaxPeaks) * (slot + l) + 6 * t + c];
            gBounceAxis[t][c] += sPeakSum[(3 * kMaxPeaks) * (slot + l) + 6 * t + 3 + c];
          }
  }
  if (lane != 0) return;
#endif
  if (!shading) return;
  if (material >= 0 && material < uMaterialCount) {
    if (uPeakCones != 0)
      for (int k = 0; k < kMaxPeaks; ++k)
        if (k < uPeakCount) gRadiance += max(peaks[k].amplitude.xyz * gPeakSum[k], vec3(0.0)) * gPeakVisibility[k];
    if (uBounce != 0) gRadiance += specularBounce();
    car = vec4(gRadiance + imageLoad(uGEmission, pixel).rgb, 1.0);
  }
  imageStore(uCarLayer, pixel, car);
  imageStore(uShadowLayer, pixel, shadow);
  counts[uint(pixel.y * uSize.x + pixel.x)] = gCount;
}
