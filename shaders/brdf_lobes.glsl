// The SG lobes of the BRDFs, a port of engine/material/brdf.cpp (isotropic warp, eq. 4.10;
// the cosine folded into the weight at the lobe axis; the Lambertian lobe is the clamped-cosine
// SG). brdf.h derives every formula; this file only mirrors it, in float. Lobe amplitudes μ are
// folded into the weights, so every lobe SG has unit amplitude.
const float kMinCosView = 1e-3;
const float kMinAlpha = 0.01;
const float kCosineSgLambda = 2.133;
const float kCosineSgAmplitude = 1.170;
const float kLobePi = 3.14159265358979323846;

// Material terms (TripleProductRenderer's table): type and parameters.
const int kBrdfNone = 0;
const int kBrdfGltf = 1;  // the glTF metallic-roughness of the G-buffer
const int kBrdfLambertian = 2;
const int kBrdfPhong = 3;
const int kBrdfBlinnPhong = 4;
const int kBrdfWard = 5;
const int kBrdfCookTorrance = 6;
const int kBrdfMetallicRoughness = 7;

const int kMaxLobes = 4;

struct Lobe {
  vec3 axis;
  float lambda;
  vec3 weight;
  bool cosine;  // the clamped-cosine lobe (Lambertian): peaks use the exact cosine
};

// λ·α² of the SG fit of a GGX/Beckmann NDF (material::NdfSgLambda), tabulated on α ∈ [kMinAlpha, 1]
// by the renderer: smooth (→ 2 − α² as α → 0), so linear interpolation is ample.
layout(std430, binding = 7) readonly buffer NdfTable { float ndfLambdaAlpha2[]; };

float ndfSgLambda(float alpha) {
  alpha = clamp(alpha, kMinAlpha, 1.0);
  int n = ndfLambdaAlpha2.length();
  float x = (alpha - kMinAlpha) / (1.0 - kMinAlpha) * float(n - 1);
  int i = min(int(x), n - 2);
  float v = mix(ndfLambdaAlpha2[i], ndfLambdaAlpha2[i + 1], x - float(i));
  return max(v, 0.0) / (alpha * alpha);
}

vec3 reflectAbout(vec3 w, vec3 about) { return 2.0 * dot(w, about) * about - w; }

// The frame's tangent of ShadingFrame::FromNormal(n, (1, 0, 0)).
vec3 frameTangent(vec3 n) {
  vec3 t = vec3(1, 0, 0) - n.x * n;
  if (length(t) < 1e-6) {
    vec3 other = abs(n.x) < 0.9 ? vec3(1, 0, 0) : vec3(0, 0, 1);
    t = other - dot(other, n) * n;
  }
  return normalize(t);
}

vec3 bendView(vec3 n, vec3 wo) {
  float c = dot(n, wo);
  if (c >= kMinCosView) return wo;
  vec3 tangential = wo - c * n;
  float l = length(tangential);
  tangential = l > 1e-6 ? tangential / l : frameTangent(n);
  return sqrt(1.0 - kMinCosView * kMinCosView) * tangential + kMinCosView * n;
}

vec3 schlick(vec3 f0, float cos_theta) {
  float m = clamp(1.0 - cos_theta, 0.0, 1.0);
  float m2 = m * m;
  return f0 + (vec3(1.0) - f0) * (m2 * m2 * m);
}

float smithLambda(bool ggx, float alpha, float cos_theta) {
  float c = clamp(cos_theta, 1e-9, 1.0);
  float tan2 = max(0.0, 1.0 - c * c) / (c * c);
  if (ggx) return 0.5 * (sqrt(1.0 + alpha * alpha * tan2) - 1.0);
  if (tan2 <= 0.0) return 0.0;
  float a = 1.0 / (alpha * sqrt(tan2));
  if (a >= 1.6) return 0.0;
  return (1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a);
}

struct LobeList {
  Lobe lobes[kMaxLobes];
  int count;
};

void pushLobe(inout LobeList list, vec3 axis, float lambda, vec3 m_at_axis, vec3 n) {
  float cos_axis = dot(n, axis);
  if (cos_axis <= 0.0 || (m_at_axis.x <= 0.0 && m_at_axis.y <= 0.0 && m_at_axis.z <= 0.0)) return;
  if (list.count >= kMaxLobes) return;
  list.lobes[list.count++] = Lobe(axis, lambda, m_at_axis * cos_axis, false);
}

void pushCosineLobe(inout LobeList list, vec3 n, vec3 weight) {
  if ((weight.x <= 0.0 && weight.y <= 0.0 && weight.z <= 0.0) || list.count >= kMaxLobes) return;
  list.lobes[list.count++] = Lobe(n, kCosineSgLambda, weight * kCosineSgAmplitude, true);
}

// Eq. 4.10: a half-vector SG around n (λ_h) to incident space for the view wo.
void warpToIncident(vec3 n, float lambda_h, vec3 wo, out vec3 axis, out float lambda) {
  float d = dot(wo, n);
  axis = normalize(reflectAbout(wo, n));
  lambda = lambda_h / (4.0 * max(abs(d), kMinCosView));
}

void pushCookTorrance(inout LobeList list, vec3 f0, float alpha, bool ggx, vec3 n, vec3 wo) {
  alpha = clamp(alpha, kMinAlpha, 1.0);
  float cos_o = dot(n, wo);
  vec3 axis;
  float lambda;
  warpToIncident(n, ndfSgLambda(alpha), wo, axis, lambda);
  float cos_i = max(dot(n, axis), kMinCosView);
  vec3 h = normalize(axis + wo);
  float g = 1.0 / (1.0 + smithLambda(ggx, alpha, cos_i) + smithLambda(ggx, alpha, cos_o));
  vec3 m = schlick(f0, dot(axis, h)) * (g / (4.0 * cos_i * cos_o)) / (kLobePi * alpha * alpha);
  pushLobe(list, axis, lambda, m, n);
}

void metallicRoughnessLobes(inout LobeList list, vec3 base, float metallic, float roughness, vec3 n, vec3 wo) {
  metallic = clamp(metallic, 0.0, 1.0);
  base = clamp(base, 0.0, 1.0);
  float r = clamp(roughness, 0.0, 1.0);
  vec3 f0 = mix(vec3(0.04), base, metallic);
  vec3 c_diff = base * (1.0 - metallic);
  pushCosineLobe(list, n, (vec3(1.0) - schlick(f0, dot(n, wo))) * c_diff / kLobePi);
  pushCookTorrance(list, f0, r * r, true, n, wo);
}

// Appends the lobes of one material term. `wo` must already be bent (bendView).
void appendLobes(inout LobeList list, int type, vec4 color, vec4 params, vec3 base, float metallic, float roughness,
                 vec3 n, vec3 wo) {
  if (type == kBrdfGltf) {
    metallicRoughnessLobes(list, base, metallic, roughness, n, wo);
  } else if (type == kBrdfMetallicRoughness) {
    metallicRoughnessLobes(list, color.rgb, params.x, params.y, n, wo);
  } else if (type == kBrdfLambertian) {
    pushCosineLobe(list, n, color.rgb / kLobePi);
  } else if (type == kBrdfPhong) {
    float e = params.x;
    pushLobe(list, reflectAbout(wo, n), max(0.0, e), color.rgb * ((e + 2.0) / (2.0 * kLobePi)), n);
  } else if (type == kBrdfBlinnPhong) {
    float s = params.x;
    vec3 axis;
    float lambda;
    warpToIncident(n, max(0.0, s), wo, axis, lambda);
    pushLobe(list, axis, lambda, color.rgb * ((s + 8.0) / (8.0 * kLobePi)), n);
  } else if (type == kBrdfWard) {
    float a = max(params.x, 1e-3);
    vec3 axis;
    float lambda;
    warpToIncident(n, 2.0 / (a * a), wo, axis, lambda);
    float cos_i = max(dot(n, axis), kMinCosView);
    pushLobe(list, axis, lambda, color.rgb / (4.0 * kLobePi * a * a * sqrt(cos_i * dot(n, wo))), n);
  } else if (type == kBrdfCookTorrance) {
    pushCookTorrance(list, color.rgb, params.x, params.y < 0.5, n, wo);
  }
}
