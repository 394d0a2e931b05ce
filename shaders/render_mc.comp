#version 450
#extension GL_GOOGLE_include_directive : require
// The brute-force baseline of TripleProductRenderer (RenderOptions::monte_carlo_samples > 0):
// the same G-buffer and voxel volume as render_shade.comp, shaded by Monte-Carlo integration of
// the environment map itself. Per sample, one-sample multiple importance sampling with the
// balance heuristic over three strategies: the map's luminance (a piecewise-constant CDF per
// texel, built by the renderer), the clamped cosine, and the GGX NDF of the pixel's glossy term;
// each direction's visibility is a shadow ray marched through the voxel mips (a cone of a
// voxel's width, so level 0 all along). The BRDFs are evaluated exactly (engine/material/brdf.cpp's
// formulas). Light from below the horizon is the map's lower half, as in the SG renderer, so that
// both shade the same model; the ground pixels get the shadow ratio (shadowed / unshadowed over
// the same samples of the Lambertian ground).
#include "sg_integral.glsl"
#include "cone_trace.glsl"
#include "brdf_lobes.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(rgba32f, binding = 0) readonly uniform image2D uGPosition;
layout(rgba32f, binding = 1) readonly uniform image2D uGNormal;
layout(rgba32f, binding = 2) readonly uniform image2D uGBase;
layout(rgba32f, binding = 3) writeonly uniform image2D uCarLayer;
layout(rgba32f, binding = 4) writeonly uniform image2D uShadowLayer;
layout(rgba32f, binding = 5) readonly uniform image2D uGEmission;
layout(binding = 1) uniform sampler2D uEnvironment;  // equirect, in the lighting's frame

struct MaterialTerm {
  ivec4 type;
  vec4 color;
  vec4 params;
};
// Per material uTermsPerMaterial BRDF terms (what it emits is in the G-buffer).
layout(std430, binding = 5) readonly buffer Materials { MaterialTerm terms[]; };
layout(std430, binding = 6) writeonly buffer Counts { uvec4 counts[]; };  // 0, shadow rays, 0, samples
layout(std430, binding = 8) readonly buffer EnvRows { float rowCdf[]; };     // H + 1, rowCdf[H] = 1
layout(std430, binding = 9) readonly buffer EnvCols { float colCdf[]; };     // H × (W + 1), per row
layout(std430, binding = 10) readonly buffer EnvPdf { float texelProb[]; };  // W × H, sums to 1

uniform ivec2 uSize;
uniform vec3 uCameraPosition;
uniform mat3 uWorldFromCamera;
uniform float uFocal;
uniform mat3 uEnvFromWorld;
uniform int uTermsPerMaterial;
uniform int uMaterialCount;
int materialRow(int material) { return material * uTermsPerMaterial; }
uniform float uSurfaceOffset;
uniform int uGround;
uniform vec2 uGroundCenter;
uniform float uGroundHalfSize;
uniform int uGroundShadowsBounce;  // render_shade.comp's groundLit
uniform float uGroundLitHalfAngle;

uniform int uExactVisibility;  // RenderOptions::monte_carlo_exact_visibility
uniform int uExactTriangles;   // 0: no geometry (everything visible)
uniform float uExactRayOffset;
uniform vec3 uGroundIrradiance;  // the ground's unshadowed irradiance (exact visibility only)

uniform int uGroundPeakCount;
uniform vec4 uGroundPeakAxis[8];  // axis, cone half-angle
uniform float uGroundPeakShare[8];

// detail::GroundLitFraction: the ground's lit fraction at q for its broad light (one cone up) and
// each traced peak (its own cone), weighted by their shares of the ground's irradiance.
float groundLitFraction(vec3 q) {
  float rest = 1.0, lit = 0.0;
  for (int k = 0; k < 8; ++k) {
    if (k >= uGroundPeakCount || uGroundPeakShare[k] <= 0.0) continue;
    lit += uGroundPeakShare[k] * traceCone(q, uGroundPeakAxis[k].xyz, uGroundPeakAxis[k].w);
    rest -= uGroundPeakShare[k];
  }
  return lit + max(rest, 0.0) * traceCone(q, vec3(0, 1, 0), uGroundLitHalfAngle);
}

float groundLitExact(vec3 q);

float groundLit(vec3 p, vec3 dir) {
  if (uGroundShadowsBounce == 0 || dir.y >= 0.0 || p.y <= 0.0) return 1.0;
  vec3 q = p - (p.y / dir.y) * dir;
  if (abs(q.x - uGroundCenter.x) > uGroundHalfSize || abs(q.z - uGroundCenter.y) > uGroundHalfSize) return 1.0;
  return uExactVisibility != 0 ? groundLitExact(vec3(q.x, 0.0, q.z)) : groundLitFraction(vec3(q.x, 0.0, q.z));
}
uniform int uSamples;
uniform uint uSeed;
uniform float uShadowRayHalfAngle;

#define BVH_BINDING 11
#include "triangle_bvh.glsl"

// The visibility of direction d from the surface point p (normal n; `origin` is p off the
// surface for the voxel cones).
float shadowRay(vec3 p, vec3 n, vec3 origin, vec3 d) {
  if (uExactVisibility != 0) return rayOccluded(p + uExactRayOffset * n, d) ? 0.0 : 1.0;
  return traceCone(origin, d, uShadowRayHalfAngle);
}

uint gRng;
uint pcgHash(uint v) {
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}
float rand01() {
  gRng = pcgHash(gRng);
  return float(gRng >> 8) * (1.0 / 16777216.0);
}

// --- The environment: lookup, sampling, density (per solid angle) -----------------------------
ivec2 envTexel(vec3 world_dir, out float sin_theta) {
  vec3 d = normalize(uEnvFromWorld * world_dir);
  ivec2 size = textureSize(uEnvironment, 0);
  float lon = atan(-d.z, d.x);
  float lat = asin(clamp(d.y, -1.0, 1.0));
  int col = int(floor((1.0 - lon / kSgPi) * 0.5 * float(size.x)));
  int row = int(floor((0.5 * kSgPi - lat) / kSgPi * float(size.y)));
  sin_theta = max(cos(lat), 1e-6);
  return ivec2(clamp(col, 0, size.x - 1), clamp(row, 0, size.y - 1));
}

vec3 envRadiance(vec3 world_dir) {
  float s;
  return texelFetch(uEnvironment, envTexel(world_dir, s), 0).rgb;
}

float envPdf(vec3 world_dir) {
  float sin_theta;
  ivec2 t = envTexel(world_dir, sin_theta);
  ivec2 size = textureSize(uEnvironment, 0);
  float texel_solid_angle = (2.0 * kSgPi / float(size.x)) * (kSgPi / float(size.y)) * sin_theta;
  return texelProb[t.y * size.x + t.x] / texel_solid_angle;
}

int upperBound(int base, int n, float u, bool rows) {  // first i in [0, n) with cdf[i + 1] > u
  int lo = 0, hi = n - 1;
  while (lo < hi) {
    int mid = (lo + hi) / 2;
    float c = rows ? rowCdf[mid + 1] : colCdf[base + mid + 1];
    if (c > u) hi = mid; else lo = mid + 1;
  }
  return lo;
}

vec3 sampleEnv() {
  ivec2 size = textureSize(uEnvironment, 0);
  int row = upperBound(0, size.y, rand01(), true);
  int col = upperBound(row * (size.x + 1), size.x, rand01(), false);
  float lon = kSgPi * (1.0 - 2.0 * (float(col) + rand01()) / float(size.x));
  float lat = 0.5 * kSgPi - kSgPi * (float(row) + rand01()) / float(size.y);
  vec3 d = vec3(cos(lat) * cos(lon), sin(lat), -cos(lat) * sin(lon));
  return normalize(transpose(uEnvFromWorld) * d);
}

// --- BRDFs (wo bent, n·wi > 0) -----------------------------------------------------------------
float ggxD(float alpha, float cos_h) {
  if (cos_h <= 0.0) return 0.0;
  float a2 = alpha * alpha, d = cos_h * cos_h * (a2 - 1.0) + 1.0;
  return a2 / (kLobePi * d * d);
}
float beckmannD(float alpha, float cos_h) {
  if (cos_h <= 0.0) return 0.0;
  float a2 = alpha * alpha, c2 = cos_h * cos_h;
  return exp((c2 - 1.0) / (a2 * c2)) / (kLobePi * a2 * c2 * c2);
}

vec3 cookTorrance(vec3 f0, float alpha, bool ggx, vec3 n, vec3 wi, vec3 wo) {
  alpha = clamp(alpha, kMinAlpha, 1.0);
  vec3 h = normalize(wi + wo);
  float ci = dot(n, wi), co = dot(n, wo);
  float d = ggx ? ggxD(alpha, dot(n, h)) : beckmannD(alpha, dot(n, h));
  float g = smithG(ggx, alpha, ci, co, false);
  return schlick(f0, dot(wi, h)) * (d * g / (4.0 * ci * co));
}

vec3 metallicRoughness(vec3 base, float metallic, float roughness, vec3 n, vec3 wi, vec3 wo) {
  metallic = clamp(metallic, 0.0, 1.0);
  base = clamp(base, 0.0, 1.0);
  float r = clamp(roughness, 0.0, 1.0);
  float alpha = clamp(r * r, kMinAlpha, 1.0);
  vec3 f0 = mix(vec3(0.04), base, metallic);
  vec3 h = normalize(wi + wo);
  float ci = dot(n, wi), co = dot(n, wo);
  vec3 fresnel = principledFresnel(f0, dot(wo, h));
  float g = smithG(true, alpha, ci, co, true);
  return base * ((1.0 - metallic) * principledDiffuseFactor(ci, co, dot(wi, wo), r) / kLobePi) +
         fresnel * (ggxD(alpha, dot(n, h)) * g / (4.0 * ci * co));
}

vec3 evalTerm(int type, vec4 color, vec4 params, vec3 base, float metallic, float roughness, vec3 n, vec3 wi, vec3 wo) {
  if (type == kBrdfGltf) return metallicRoughness(base, metallic, roughness, n, wi, wo);
  if (type == kBrdfMetallicRoughness) return metallicRoughness(color.rgb, params.x, params.y, n, wi, wo);
  if (type == kBrdfLambertian) return color.rgb / kLobePi;
  if (type == kBrdfPhong) {
    float c = dot(reflectAbout(wo, n), wi);
    return c > 0.0 ? color.rgb * ((params.x + 2.0) / (2.0 * kLobePi) * pow(c, params.x)) : vec3(0.0);
  }
  if (type == kBrdfBlinnPhong) {
    float c = dot(n, normalize(wi + wo));
    return c > 0.0 ? color.rgb * ((params.x + 8.0) / (8.0 * kLobePi) * pow(c, params.x)) : vec3(0.0);
  }
  if (type == kBrdfWard) {
    vec3 h = normalize(wi + wo);
    float hn = dot(h, n), a = params.x;
    if (hn <= 0.0) return vec3(0.0);
    float tan2 = max(0.0, 1.0 - hn * hn) / (hn * hn);
    return color.rgb * (exp(-tan2 / (a * a)) / (4.0 * kLobePi * a * a * sqrt(dot(n, wi) * dot(n, wo))));
  }
  if (type == kBrdfCookTorrance) return cookTorrance(color.rgb, params.x, params.y < 0.5, n, wi, wo);
  if (type == kBrdfSheen) {
    // material::Sheen: the Charlie D with Neubelt's V.
    float alpha = max(params.x * params.x, kMinSheenAlpha);
    float nh = dot(n, normalize(wi + wo)), ci = dot(n, wi), co = max(dot(n, wo), 0.0);
    float d = (2.0 + 1.0 / alpha) * pow(sqrt(max(0.0, 1.0 - nh * nh)), 1.0 / alpha) / (2.0 * kLobePi);
    return color.rgb * (d / (4.0 * max(ci + co - ci * co, 1e-9)));
  }
  return vec3(0.0);
}

// The width of a term's glossy lobe as a GGX α for the NDF strategy; 0: no glossy lobe.
float glossyAlpha(int type, vec4 params, float roughness) {
  if (type == kBrdfGltf) return clamp(roughness * roughness, kMinAlpha, 1.0);
  if (type == kBrdfMetallicRoughness) return clamp(params.y * params.y, kMinAlpha, 1.0);
  if (type == kBrdfCookTorrance || type == kBrdfWard) return clamp(params.x, kMinAlpha, 1.0);
  if (type == kBrdfPhong || type == kBrdfBlinnPhong) return clamp(sqrt(2.0 / (params.x + 2.0)), kMinAlpha, 1.0);
  return 0.0;
}

vec3 tangentToWorld(vec3 n, vec3 v) {
  vec3 helper = abs(n.z) < 0.9 ? vec3(0, 0, 1) : vec3(1, 0, 0);
  vec3 t = normalize(cross(helper, n)), b = cross(n, t);
  return v.x * t + v.y * b + v.z * n;
}

vec3 sampleCosine(vec3 n) {
  float u = rand01(), phi = 2.0 * kSgPi * rand01();
  float r = sqrt(u);
  return tangentToWorld(n, vec3(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u))));
}

vec3 sampleGgx(vec3 n, vec3 wo, float alpha) {
  float u = rand01(), phi = 2.0 * kSgPi * rand01();
  float cos2 = (1.0 - u) / (1.0 + (alpha * alpha - 1.0) * u);
  float c = sqrt(cos2), s = sqrt(max(0.0, 1.0 - cos2));
  vec3 h = tangentToWorld(n, vec3(s * cos(phi), s * sin(phi), c));
  return reflectAbout(wo, h);
}

float ggxPdf(vec3 n, vec3 wo, vec3 wi, float alpha) {
  vec3 h = normalize(wi + wo);
  float oh = abs(dot(wo, h));
  return oh > 0.0 ? ggxD(alpha, dot(n, h)) * max(dot(n, h), 0.0) / (4.0 * oh) : 0.0;
}

const float kEnvShare = 0.5;

// The ground's lit fraction at q, E_shadowed / E, estimated by one sample of the same
// strategies as the ground pixels below: unbiased, so the product with the car's own sample is.
// Its random numbers come from a stream of their own, so the car's samples stay those of the
// voxel shader with the same seed (paired comparisons).
uint gGroundRng;
float groundLitExact(vec3 q) {
  const vec3 up = vec3(0, 1, 0);
  uint car_rng = gRng;
  gRng = gGroundRng;
  vec3 wi = rand01() < kEnvShare ? sampleEnv() : sampleCosine(up);
  gGroundRng = gRng;
  gRng = car_rng;
  float cos_i = wi.y;
  if (cos_i <= 0.0) return 0.0;
  float pdf = kEnvShare * envPdf(wi) + (1.0 - kEnvShare) * cos_i / kLobePi;
  if (!(pdf > 0.0) || rayOccluded(q + uExactRayOffset * up, wi)) return 0.0;
  vec3 value = envRadiance(wi) * (cos_i / pdf);
  vec3 w = vec3(0.2126, 0.7152, 0.0722);
  return dot(w, value) / max(dot(w, uGroundIrradiance), 1e-30);
}

void main() {
  ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
  if (pixel.x >= uSize.x || pixel.y >= uSize.y) return;
  uint index = uint(pixel.y * uSize.x + pixel.x);
  gRng = pcgHash(index ^ pcgHash(uSeed));
  gGroundRng = pcgHash(gRng ^ 0x9e3779b9u);
  uvec4 count = uvec4(0);
  vec4 gp = imageLoad(uGPosition, pixel);
  vec4 car = vec4(0.0);
  vec4 shadow = vec4(1.0, 1.0, 1.0, 0.0);
  int material = int(gp.w + 0.5) - 1;
  if (material >= 0 && material < uMaterialCount) {
    vec4 gn = imageLoad(uGNormal, pixel);
    vec4 gb = imageLoad(uGBase, pixel);
    vec3 p = gp.xyz, n = normalize(gn.xyz);
    vec3 wo = bendView(n, normalize(uCameraPosition - p));
    vec3 origin = p + uSurfaceOffset * n;
    float alpha = 0.0;
    for (int k = 0; k < uTermsPerMaterial; ++k) {
      MaterialTerm term = terms[materialRow(material) + k];
      alpha = max(alpha, glossyAlpha(term.type.x, term.params, gn.w));
    }
    float q_ggx = alpha > 0.0 ? 0.5 * (1.0 - kEnvShare) : 0.0;
    float q_cos = 1.0 - kEnvShare - q_ggx;
    vec3 sum = vec3(0.0);
    for (int s = 0; s < uSamples; ++s) {
      float pick = rand01();
      vec3 wi = pick < kEnvShare ? sampleEnv() : (pick < kEnvShare + q_cos ? sampleCosine(n) : sampleGgx(n, wo, alpha));
      float cos_i = dot(n, wi);
      count.w += 1u;
      if (cos_i <= 0.0) continue;
      float pdf = kEnvShare * envPdf(wi) + q_cos * cos_i / kLobePi + (q_ggx > 0.0 ? q_ggx * ggxPdf(n, wo, wi, alpha) : 0.0);
      if (!(pdf > 0.0)) continue;
      vec3 f = vec3(0.0);
      for (int k = 0; k < uTermsPerMaterial; ++k) {
        MaterialTerm term = terms[materialRow(material) + k];
        f += evalTerm(term.type.x, term.color, term.params, gb.rgb, gb.a, gn.w, n, wi, wo);
      }
      vec3 value = f * envRadiance(wi) * (cos_i / pdf);
      if (value == vec3(0.0)) continue;
      sum += value * (shadowRay(p, n, origin, wi) * groundLit(origin, wi));
      count.y += 1u;
    }
    car = vec4(sum / float(max(uSamples, 1)) + imageLoad(uGEmission, pixel).rgb, 1.0);
  } else if (uGround != 0) {
    vec3 dir = normalize(uWorldFromCamera * vec3((vec2(pixel) + 0.5 - 0.5 * vec2(uSize)) / uFocal, 1.0));
    float t = dir.y < 0.0 ? -uCameraPosition.y / dir.y : -1.0;
    vec3 p = uCameraPosition + t * dir;
    if (t > 0.0 && abs(p.x - uGroundCenter.x) <= uGroundHalfSize && abs(p.z - uGroundCenter.y) <= uGroundHalfSize) {
      p.y = 0.0;
      const vec3 up = vec3(0, 1, 0);
      vec3 shaded = vec3(0.0), unshadowed = vec3(0.0);
      for (int s = 0; s < uSamples; ++s) {
        vec3 wi = rand01() < kEnvShare ? sampleEnv() : sampleCosine(up);
        float cos_i = wi.y;
        count.w += 1u;
        if (cos_i <= 0.0) continue;
        float pdf = kEnvShare * envPdf(wi) + (1.0 - kEnvShare) * cos_i / kLobePi;
        if (!(pdf > 0.0)) continue;
        vec3 value = envRadiance(wi) * (cos_i / pdf);
        unshadowed += value;
        shaded += value * shadowRay(p, up, p, wi);
        count.y += 1u;
      }
      shadow.a = 1.0;
      for (int c = 0; c < 3; ++c) shadow[c] = unshadowed[c] > 0.0 ? clamp(shaded[c] / unshadowed[c], 0.0, 1.0) : 1.0;
    }
  }
  imageStore(uCarLayer, pixel, car);
  imageStore(uShadowLayer, pixel, shadow);
  counts[index] = count;
}
