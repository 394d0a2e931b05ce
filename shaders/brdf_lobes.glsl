// The SG lobes of the BRDFs, a port of engine/material/brdf.cpp (eq. 4.10's isotropic warp or
// the anisotropic split; the cosine at the lobe axis or as the clamped-cosine SG; the Lambertian
// lobe is the clamped-cosine SG). Needs sg_integral.glsl. brdf.h derives every formula; this file
// only mirrors it, in float. Lobe amplitudes μ are folded into the weights, so every lobe SG has
// unit amplitude.
const float kMinCosView = 1e-3;
const float kMinAlpha = 0.002;
const float kMinSheenAlpha = 0.07 * 0.07;  // material::kMinSheenAlpha
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
const int kBrdfSheen = 8;  // material::Sheen: color, params.x its roughness


// Per α ∈ [kMinAlpha, 1] (kNdfTableNodes uniform nodes, filled by the renderer) two vec4: x of the
// first is λ·α² of the one-SG fit of a GGX/Beckmann NDF (material::NdfSgLambda); the second GGX's
// two SGs (material::GgxSg): λ_0 α², λ_1 α², μ_0 π α², μ_1 π α². Smooth in α (λα² → 2 − α² as
// α → 0), so linear interpolation is ample. Then material::SheenAlbedoTable, four values a vec4.
layout(std430, binding = 7) readonly buffer NdfTable { vec4 ndfTable[]; };
const int kNdfTableNodes = 512;
const int kSheenTableNodes = 33;

vec4 ndfTableAt(float alpha, int column) {
  alpha = clamp(alpha, kMinAlpha, 1.0);
  int n = kNdfTableNodes;
  float x = (alpha - kMinAlpha) / (1.0 - kMinAlpha) * float(n - 1);
  int i = min(int(x), n - 2);
  return mix(ndfTable[2 * i + column], ndfTable[2 * i + 2 + column], x - float(i));
}

// material::SheenAlbedo: bilinear in the table's nodes over n·wo and the roughness.
float sheenTableAt(int i, int j) {
  int k = j * kSheenTableNodes + i;
  return ndfTable[2 * kNdfTableNodes + k / 4][k % 4];
}
float sheenAlbedo(float cos_view, float roughness) {
  float x = clamp(cos_view, 0.0, 1.0) * float(kSheenTableNodes - 1);
  float y = clamp(roughness, 0.0, 1.0) * float(kSheenTableNodes - 1);
  int i = min(int(x), kSheenTableNodes - 2), j = min(int(y), kSheenTableNodes - 2);
  float fx = x - float(i), fy = y - float(j);
  return mix(mix(sheenTableAt(i, j), sheenTableAt(i + 1, j), fx), mix(sheenTableAt(i, j + 1), sheenTableAt(i + 1, j + 1), fx),
             fy);
}

float ndfSgLambda(float alpha) {
  alpha = clamp(alpha, kMinAlpha, 1.0);
  return max(ndfTableAt(alpha, 0).x, 0.0) / (alpha * alpha);
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

// material::FresnelOf(kPrincipled): Blender's Principled BSDF (v1), as the glTF importer makes it
// (specular 0.5, so IOR 1.5): the dielectric Fresnel of IOR 1.5 remapped from its 0.04 at normal
// incidence to f0 (f0 + (1 − f0)(F(cos) − 0.04)/0.96), where Schlick's (1 − cos)⁵ stands for it.
vec3 principledFresnel(vec3 f0, float cos_theta) {
  float c = clamp(abs(cos_theta), 0.0, 1.0);
  float g = sqrt(1.25 + c * c);  // √(η² − 1 + c²), η = 1.5
  float a = (g - c) / (g + c);
  float b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
  float f = 0.5 * a * a * (1.0 + b * b);
  return f0 + (vec3(1.0) - f0) * max((f - 0.04) / 0.96, 0.0);
}

vec3 fresnelOf(bool principled, vec3 f0, float cos_theta) {
  return principled ? principledFresnel(f0, cos_theta) : schlick(f0, cos_theta);
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

// material::SmithG: height-correlated, or (`separable`, the Principled BSDF in Cycles 3.x) the
// product G1(wi) G1(wo).
float smithG(bool ggx, float alpha, float cos_i, float cos_o, bool separable) {
  float li = smithLambda(ggx, alpha, cos_i), lo = smithLambda(ggx, alpha, cos_o);
  return separable ? 1.0 / ((1.0 + li) * (1.0 + lo)) : 1.0 / (1.0 + li + lo);
}

// Cycles' principled diffuse (Burley 2015) relative to 1/π, and its directional albedo
// (material::PrincipledDiffuseFactor / PrincipledDiffuseAlbedo derive them).
float principledDiffuseFactor(float cos_i, float cos_o, float cos_io, float roughness) {
  float a = clamp(1.0 - cos_i, 0.0, 1.0), b = clamp(1.0 - cos_o, 0.0, 1.0);
  float fl = a * a * a * a * a, fv = b * b * b * b * b;
  float rr = clamp(roughness, 0.0, 1.0) * (1.0 + cos_io);
  return (1.0 - 0.5 * fl) * (1.0 - 0.5 * fv) + rr * (fl + fv + fl * fv * (rr - 1.0));
}

float principledDiffuseAlbedo(float cos_o, float roughness) {
  float mu = clamp(cos_o, 0.0, 1.0), r = clamp(roughness, 0.0, 1.0);
  float b = 1.0 - mu;
  float fv = b * b * b * b * b;
  return (1.0 - 0.5 * fv) * (41.0 / 42.0) + fv * r * (1.0 + 2.0 * mu / 3.0) + r * (1.0 - fv) * (1.0 / 21.0 + mu / 84.0) +
         fv * r * r * (1.0 / 21.0 + mu / 42.0 + (11.0 - 9.0 * mu * mu) / 504.0);
}

// RenderOptions::lobes (material::LobeOptions): 1 = WarpMode::kAnisotropicSplit,
// 1 = CosineTerm::kAsSg.
uniform int uWarpSplit;
uniform int uCosineAsSg;
const int kMaxSplitLobes = 15;  // material::kMaxAnisotropicLobes

// Eq. 4.10: a half-vector SG around n (λ_h) to incident space for the view wo.
void warpToIncident(vec3 n, float lambda_h, vec3 wo, out vec3 axis, out float lambda) {
  float d = dot(wo, n);
  axis = normalize(reflectAbout(wo, n));
  lambda = lambda_h / (4.0 * max(abs(d), kMinCosView));
}

// M of a warped lobe at incident direction wi (material::PushWarped's m_of): kind 0 a constant
// (Blinn-Phong), 1 Cook-Torrance (f0 = color, α, GGX or Beckmann), 2 isotropic Ward (ρs = color, α).
const int kMConstant = 0;
const int kMCookTorrance = 1;
const int kMWard = 2;

vec3 mAt(int kind, vec3 color, float alpha, bool ggx, bool principled, vec3 n, vec3 wo, vec3 wi) {
  if (kind == kMConstant) return color;
  float cos_i = max(dot(n, wi), kMinCosView), cos_o = dot(n, wo);
  if (kind == kMWard) return color / (4.0 * kLobePi * alpha * alpha * sqrt(cos_i * cos_o));
  vec3 h = normalize(wi + wo);
  float g = smithG(ggx, alpha, cos_i, cos_o, principled);
  return fresnelOf(principled, color, dot(wi, h)) * (g / (4.0 * cos_i * cos_o));
}

// material::PushWarped: the half-vector SG (n, λ_h, amplitude) warped by eq. 4.10, or split into
// a row of isotropic SGs along the plane of incidence (material::SplitRow; brdf.h says why).
// One material term's lobes, described so that lobe i can be computed on its own (termLobe):
// the shader then has a single call site for the shading of a lobe. Inlined at every call site
// of a streaming push, the cone tracing made llvmpipe's compile take minutes.
struct TermLobes {
  int count;            // lobes, the dropped ones included
  bool has_cosine;      // lobe 0 is the clamped-cosine lobe
  vec3 cosine_weight;
  vec3 cosine_linear;   // its linear factor (material::Lobe::linear)
  vec3 cosine_grazing;  // its grazing factor's coefficients (material::Lobe::grazing)
  int kind;             // -1: none; kMConstant, kMCookTorrance, kMWard: a warped lobe; 3: Phong
  vec3 color;           // M's colour parameter (Phong: its weight)
  float alpha, amplitude;
  bool ggx;
  bool principled;      // Cook-Torrance's F and G: the Principled BSDF's (glTF metallic-roughness) or Schlick's
                        // and the height-correlated Smith (material::CookTorrance::principled)
  vec3 axis;            // warped (or Phong) axis
  float lambda;         // its λ (Phong's exponent; eq. 4.10's warp)
  float lambda_h;       // the half-vector λ
  bool split;
  vec3 across;
  float split_lambda, s_conv, delta, scale;
  int half_count;
  bool tail;            // GGX's tail SG (material::GgxSg), eq. 4.10's warp, after the others
  vec3 tail_axis;
  float tail_lambda, tail_amplitude;
  float tail_share;     // material::GgxTailShare
};
const int kMPhong = 3;

void describeWarped(inout TermLobes t, float lambda_h, float amplitude, int kind, vec3 color, float alpha, bool ggx,
                    vec3 n, vec3 wo) {
  t.kind = kind;
  t.color = color;
  t.alpha = alpha;
  t.ggx = ggx;
  t.amplitude = amplitude;
  t.lambda_h = lambda_h;
  warpToIncident(n, lambda_h, wo, t.axis, t.lambda);
  vec3 across = n - dot(n, t.axis) * t.axis;
  t.split = false;
  t.half_count = 0;
  if (uWarpSplit != 0 && length(across) >= 1e-5 && lambda_h > 0.0) {
    t.across = normalize(across);
    float cos_d = max(abs(dot(wo, n)), kMinCosView);
    float s_h = inversesqrt(lambda_h);
    float s_short = 2.0 * cos_d * s_h, s_long = 2.0 * s_h;
    t.split_lambda = 1.0 / (s_short * s_short);
    t.s_conv = sqrt(max(0.0, s_long * s_long - s_short * s_short));
    t.split = true;
    if (t.s_conv >= 1e-3 * s_short) {
      float s_eff = s_short * t.s_conv / s_long;
      t.half_count = clamp(int(floor(3.0 * t.s_conv / (1.8 * s_eff))), 1, (kMaxSplitLobes - 1) / 2);
      t.delta = 3.0 * t.s_conv / float(t.half_count);
      float sum = 0.0;
      for (int k = -t.half_count; k <= t.half_count; ++k) {
        float tau = float(k) * t.delta;
        sum += exp(-tau * tau / (2.0 * t.s_conv * t.s_conv));
      }
      t.scale = (s_long / s_short) / sum;
    }
  }
  t.count += 2 * t.half_count + 1;
}

// GGX (material::PushCookTorrance): the peak SG warped as uWarpSplit says, the tail by eq. 4.10.
void describeGgx(inout TermLobes t, vec3 f0, float alpha, vec3 n, vec3 wo) {
  vec4 e = max(ndfTableAt(alpha, 1), vec4(0.0)) / (alpha * alpha);
  describeWarped(t, e.x, e.z / kLobePi, kMCookTorrance, f0, alpha, true, n, wo);
  t.tail = e.w > 0.0;
  if (!t.tail) return;
  t.tail_amplitude = e.w / kLobePi;
  warpToIncident(n, e.y, wo, t.tail_axis, t.tail_lambda);
  float i0 = e.z * (e.x < 1e-6 ? 2.0 : (1.0 - exp(-2.0 * e.x)) / e.x);
  float i1 = e.w * (e.y < 1e-6 ? 2.0 : (1.0 - exp(-2.0 * e.y)) / e.y);
  t.tail_share = i1 / (i0 + i1);
  t.count += 1;
}

TermLobes describeTerm(int type, vec4 color, vec4 params, vec3 base, float metallic, float roughness, vec3 n, vec3 wo) {
  TermLobes t;
  t.count = 0;
  t.has_cosine = false;
  t.cosine_linear = vec3(0.0);
  t.cosine_grazing = vec3(0.0);
  t.kind = -1;
  t.principled = false;
  t.tail = false;
  if (type == kBrdfGltf || type == kBrdfMetallicRoughness) {
    if (type == kBrdfMetallicRoughness) {
      base = color.rgb;
      metallic = params.x;
      roughness = params.y;
    }
    metallic = clamp(metallic, 0.0, 1.0);
    base = clamp(base, 0.0, 1.0);
    float r = clamp(roughness, 0.0, 1.0);
    vec3 f0 = mix(vec3(0.04), base, metallic);
    t.has_cosine = true;
    // material::LobesOf(MetallicRoughness): f_d π = a0 + a1 wi·wo + FL B(wi·wo), the linear
    // factor and the grazing factor's coefficients relative to a0.
    float mu = dot(n, wo);
    float b = 1.0 - clamp(mu, 0.0, 1.0);
    float fv = b * b * b * b * b;
    float a1 = fv * r, a0 = 1.0 - 0.5 * fv + fv * r;
    t.cosine_weight = base * ((1.0 - metallic) * a0 / kLobePi);
    t.cosine_linear = (a1 / a0) * wo;
    t.cosine_grazing = vec3(-0.5 * (1.0 - 0.5 * fv) + r * (1.0 - fv) + r * r * fv, r * (1.0 - fv) + 2.0 * r * r * fv,
                            r * r * fv) /
                       a0;
    t.count = 1;
    float alpha = clamp(r * r, kMinAlpha, 1.0);
    t.principled = true;
    describeGgx(t, f0, alpha, n, wo);
  } else if (type == kBrdfLambertian) {
    t.has_cosine = true;
    t.cosine_weight = color.rgb / kLobePi;
    t.count = 1;
  } else if (type == kBrdfSheen) {
    // material::LobesOf(Sheen): a clamped cosine of the sheen's albedo for this view, E(wo)/π.
    t.has_cosine = true;
    t.cosine_weight = color.rgb * (sheenAlbedo(dot(n, wo), params.x) / kLobePi);
    t.count = 1;
  } else if (type == kBrdfPhong) {
    float e = params.x;
    t.kind = kMPhong;
    t.axis = reflectAbout(wo, n);
    t.lambda = max(0.0, e);
    t.color = color.rgb * ((e + 2.0) / (2.0 * kLobePi));
    t.amplitude = 1.0;
    t.count = 1;
  } else if (type == kBrdfBlinnPhong) {
    float s = params.x;
    describeWarped(t, max(0.0, s), 1.0, kMConstant, color.rgb * ((s + 8.0) / (8.0 * kLobePi)), 0.0, true, n, wo);
  } else if (type == kBrdfWard) {
    float a = max(params.x, 1e-3);
    describeWarped(t, 2.0 / (a * a), 1.0, kMWard, color.rgb, a, true, n, wo);
  } else if (type == kBrdfCookTorrance) {
    float alpha = clamp(params.x, kMinAlpha, 1.0);
    if (params.y < 0.5) {
      describeGgx(t, color.rgb, alpha, n, wo);
    } else {
      describeWarped(t, ndfSgLambda(alpha), 1.0 / (kLobePi * alpha * alpha), kMCookTorrance, color.rgb, alpha, false,
                     n, wo);
    }
  }
  return t;
}

// Lobe i's material::Lobe::tail_share: GGX's tail SG, after the peak's lobes, has its share of D.
float termLobeTailShare(in TermLobes t, int i) {
  return t.tail && i == (t.has_cosine ? 1 : 0) + 2 * t.half_count + 1 ? t.tail_share : 0.0;
}

// Lobe i of the term (material::Push): false when it is dropped (its axis below the horizon or
// no weight), as material::AppendLobes leaves it out.
bool termLobe(in TermLobes t, int i, vec3 n, vec3 wo, out vec3 axis, out float lambda, out vec3 weight,
              out bool cosine) {
  cosine = false;
  if (t.has_cosine) {
    if (i == 0) {
      axis = n;
      lambda = kCosineSgLambda;
      weight = t.cosine_weight;  // the clamped cosine itself (material::Lobe::clamped_cosine)
      cosine = true;
      return t.cosine_weight.x > 0.0 || t.cosine_weight.y > 0.0 || t.cosine_weight.z > 0.0;
    }
    --i;
  }
  float amplitude = t.amplitude;
  vec3 m;
  if (t.tail && i == 2 * t.half_count + 1) {
    axis = t.tail_axis;
    lambda = t.tail_lambda;
    amplitude = t.tail_amplitude;
    m = mAt(t.kind, t.color, t.alpha, t.ggx, t.principled, n, wo, axis);
  } else if (t.kind == kMPhong) {
    axis = t.axis;
    lambda = t.lambda;
    m = t.color;
  } else if (!t.split) {
    axis = t.axis;
    lambda = t.lambda;
    m = mAt(t.kind, t.color, t.alpha, t.ggx, t.principled, n, wo, axis);
  } else if (t.half_count == 0) {
    axis = t.axis;
    lambda = t.split_lambda;
    m = mAt(t.kind, t.color, t.alpha, t.ggx, t.principled, n, wo, axis);
  } else {
    float tau = float(i - t.half_count) * t.delta;
    axis = normalize(t.axis + tau * t.across);
    lambda = t.split_lambda;
    amplitude *= t.scale * exp(-tau * tau / (2.0 * t.s_conv * t.s_conv));
    m = mAt(t.kind, t.color, t.alpha, t.ggx, t.principled, n, wo, axis);
  }
  float cos_axis = dot(n, axis);
  if (cos_axis <= 0.0 || (m.x <= 0.0 && m.y <= 0.0 && m.z <= 0.0)) return false;
  if (uCosineAsSg == 0) {
    weight = m * (amplitude * cos_axis);
  } else {
    SgProduct q = sgProduct(axis, lambda, n, kCosineSgLambda);
    axis = q.axis;
    lambda = q.lambda;
    weight = m * (amplitude * kCosineSgAmplitude * exp(q.log_amplitude));
  }
  return true;
}

// material::GgxLobeResidual: a GGX term's specular D F G / (4 n·wo) at wi (its cosine included)
// minus the term's non-cosine lobes there; 0 for terms without GGX.
vec3 ggxLobeResidual(in TermLobes t, vec3 n, vec3 wo, vec3 wi) {
  if (t.kind != kMCookTorrance || !t.ggx) return vec3(0.0);
  float cos_i = dot(n, wi), cos_o = dot(n, wo);
  vec3 r = vec3(0.0);
  if (cos_i > 0.0) {
    vec3 h = normalize(wi + wo);
    float a2 = t.alpha * t.alpha, ch = dot(n, h);
    float d = ch > 0.0 ? (ch * ch * (a2 - 1.0) + 1.0) : 1.0;
    float ndf = ch > 0.0 ? a2 / (kLobePi * d * d) : 0.0;
    float g = smithG(true, t.alpha, cos_i, cos_o, t.principled);
    r = fresnelOf(t.principled, t.color, dot(wi, h)) * (ndf * g / (4.0 * cos_o));
  }
  for (int i = t.has_cosine ? 1 : 0; i < t.count; ++i) {
    vec3 axis, weight;
    float lambda;
    bool cosine;
    if (termLobe(t, i, n, wo, axis, lambda, weight, cosine)) r -= weight * exp(lambda * (dot(axis, wi) - 1.0));
  }
  return r;
}

// material::GgxResidualUnderSgLight for a unit light SG (axis, λ): the 7-point degree-5 rule of
// the light as a 2D Gaussian of σ = 1/√λ in its tangent plane.
vec3 ggxResidualUnderLight(in TermLobes t, vec3 n, vec3 wo, vec3 c, float lambda) {
  if (t.kind != kMCookTorrance || !t.ggx) return vec3(0.0);
  vec3 helper = abs(c.y) < 0.9 ? vec3(0, 1, 0) : vec3(1, 0, 0);
  vec3 e1 = normalize(cross(c, helper)), e2 = cross(c, e1);
  float r = 2.0 / sqrt(max(lambda, 1e-6));
  vec3 sum = 0.5 * ggxLobeResidual(t, n, wo, c);
  for (int k = 0; k < 6; ++k) {
    float a = float(k) * kLobePi / 3.0;
    sum += ggxLobeResidual(t, n, wo, normalize(c + r * (cos(a) * e1 + sin(a) * e2))) / 12.0;
  }
  return sum * sgIntegral(lambda);
}
