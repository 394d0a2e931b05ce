#version 450
// G-buffer of the triple-product renderer: world position and material index + 1 (0 = empty),
// shading normal (normal map applied when the material has one) and
// perceptual roughness, linear base colour and metallic, and the radiance the surface emits (glTF:
// emissive factor × strength × emissive texture).
in vec3 vPosition;
in vec3 vNormal;
in vec2 vUv0;
in vec2 vUv1;
in vec4 vTangent;

layout(location = 0) out vec4 outPosition;
layout(location = 1) out vec4 outNormal;
layout(location = 2) out vec4 outBase;
layout(location = 3) out vec4 outEmission;

layout(binding = 0) uniform sampler2D uBaseColorTex;  // sRGB texture format: sampled linear
layout(binding = 1) uniform sampler2D uMetalRoughTex;  // G roughness, B metallic
layout(binding = 2) uniform sampler2D uNormalTex;
layout(binding = 3) uniform sampler2D uEmissiveTex;  // sRGB texture format: sampled linear

uniform float uMaterialId;  // material index + 1
uniform vec4 uBaseColorFactor;
uniform float uMetallicFactor;
uniform float uRoughnessFactor;
uniform float uNormalScale;
uniform vec3 uEmission;  // factor × strength; 0 under a material override
uniform float uTransmission;  // PbrMaterial::transmission
uniform float uAlphaCutoff;  // < 0: opaque
uniform vec3 uCameraPosition;
// Per texture (base, metal-rough, normal, emissive): enabled, texcoord set, KHR_texture_transform.
uniform ivec2 uTexUse[4];     // (enabled, texcoord)
uniform vec4 uTexOffsetScale[4];  // offset xy, scale zw
uniform float uTexRotation[4];

vec2 texUv(int k) {
  vec2 uv = uTexUse[k].y == 1 ? vUv1 : vUv0;
  uv *= uTexOffsetScale[k].zw;
  float c = cos(uTexRotation[k]), s = sin(uTexRotation[k]);
  // glTF's KHR_texture_transform rotation matrix (counter-clockwise in UV space).
  uv = vec2(c * uv.x + s * uv.y, -s * uv.x + c * uv.y);
  return uv + uTexOffsetScale[k].xy;
}

// RenderOptions::valid_reflection_normals: the shading normal n tilted, in the plane of n and the
// face's normal ng, just enough that the view direction wo mirrored about it leaves the face at a
// height (its cosine to ng) of at least min(0.9 ng·wo, 0.01), as Cycles bends every closure's
// normal: the mirror direction is lifted to that height, keeping its component across the plane,
// and the new normal is its half-vector with wo.
uniform int uValidReflectionNormals;
vec3 validReflectionNormal(vec3 ng, vec3 wo, vec3 n) {
  if (!(dot(ng, ng) > 0.5)) return n;
  float height = min(0.9 * dot(ng, wo), 0.01);
  vec3 r = 2.0 * dot(n, wo) * n - wo;
  if (dot(ng, r) >= height) return n;
  vec3 x = n - dot(n, ng) * ng;
  float lx = length(x);
  if (lx < 1e-6) return n;
  x /= lx;
  vec3 y = cross(ng, x);
  float ry = -dot(wo, y);
  float rx2 = 1.0 - height * height - ry * ry;
  if (rx2 < 0.0) return ng;
  vec3 lifted = (dot(r, x) >= 0.0 ? 1.0 : -1.0) * sqrt(rx2) * x + height * ng + ry * y;
  vec3 h = wo + lifted;
  return dot(h, h) > 1e-12 ? normalize(h) : ng;
}

// The normal map's tangent frame at this pixel: the mesh's tangents where it has them; otherwise the
// frame its texture coordinates give the surface, as glTF asks of a viewer when tangents are
// missing: t along ∂p/∂u (solved from the pixel's derivatives of p and uv), b = n × t pointing
// against ∂p/∂v (the map's +y is −v; a mirrored layout flips it, as MikkTSpace's w does).
// False where the coordinates give no frame (degenerate, or constant uv). dp1, dp2 and duv1, duv2:
// the screen derivatives (x, y) of the position and of the map's uv, taken in main's uniform
// control flow.
bool normalMapFrame(vec3 n, vec3 dp1, vec3 dp2, vec2 duv1, vec2 duv2, out vec3 t, out vec3 b) {
  t = vec3(0.0);
  b = vec3(0.0);
  if (dot(vTangent.xyz, vTangent.xyz) > 1e-12) {
    t = normalize(vTangent.xyz - dot(vTangent.xyz, n) * n);
    b = cross(n, t) * (vTangent.w < 0.0 ? -1.0 : 1.0);
    return true;
  }
  float det = duv1.x * duv2.y - duv1.y * duv2.x;
  if (!(abs(det) > 1e-20)) return false;
  vec3 dpdu = (dp1 * duv2.y - dp2 * duv1.y) / det;
  vec3 dpdv = (dp2 * duv1.x - dp1 * duv2.x) / det;
  vec3 across = dpdu - dot(dpdu, n) * n;
  if (!(dot(across, across) > 1e-24)) return false;
  t = normalize(across);
  b = cross(n, t);
  if (dot(b, dpdv) > 0.0) b = -b;
  return true;
}

void main() {
  vec4 base = uBaseColorFactor;
  if (uTexUse[0].x != 0) base *= texture(uBaseColorTex, texUv(0));
  if (uAlphaCutoff >= 0.0 && base.a < uAlphaCutoff) discard;
  float roughness = uRoughnessFactor, metallic = uMetallicFactor;
  if (uTexUse[1].x != 0) {
    vec4 mr = texture(uMetalRoughTex, texUv(1));
    roughness *= mr.g;
    metallic *= mr.b;
  }
  vec3 n = vNormal;
  // A degenerate interpolated normal falls back to the face's own.
  vec3 dp_dx = dFdx(vPosition), dp_dy = dFdy(vPosition);
  vec3 face = cross(dp_dx, dp_dy);
  if (dot(face, uCameraPosition - vPosition) < 0.0) face = -face;
  if (!(dot(n, n) > 1e-12)) n = face;
  if (!(dot(n, n) > 1e-20)) n = vec3(0, 1, 0);
  n = normalize(n);
  vec2 normal_uv = texUv(2);
  vec2 duv_dx = dFdx(normal_uv), duv_dy = dFdy(normal_uv);
  vec3 t, b;
  if (uTexUse[2].x != 0 && normalMapFrame(n, dp_dx, dp_dy, duv_dx, duv_dy, t, b)) {
    vec3 tn = texture(uNormalTex, normal_uv).xyz * 2.0 - 1.0;
    tn.xy *= uNormalScale;
    vec3 m = tn.x * t + tn.y * b + tn.z * n;
    if (dot(m, m) > 1e-12) n = normalize(m);
  }
  // Seen from behind (a double-sided panel, or a back face that won the depth test): shade the
  // side that faces the camera.
  if (dot(n, uCameraPosition - vPosition) < 0.0 && !gl_FrontFacing) n = -n;
  if (uValidReflectionNormals != 0)
    n = validReflectionNormal(normalize(face), normalize(uCameraPosition - vPosition), n);
  outPosition = vec4(vPosition, uMaterialId);
  outNormal = vec4(n, roughness);
  // PbrMaterial::transmission: the dielectric's diffuse loses the transmitted share; scaling the
  // base colour by 1 − T (1 − metallic) does that exactly for a dielectric (F0 = 0.04 whatever
  // the base) and nothing to a metal, as the extension's layering has it.
  outBase = vec4(base.rgb * (1.0 - uTransmission * (1.0 - clamp(metallic, 0.0, 1.0))), metallic);
  vec3 emission = uEmission;
  if (uTexUse[3].x != 0 && emission != vec3(0.0)) emission *= texture(uEmissiveTex, texUv(3)).rgb;
  outEmission = vec4(emission, 0.0);
}
