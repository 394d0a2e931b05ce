#version 450
#extension GL_GOOGLE_include_directive : require
// Magnification of the reconstruction to the next level's grid, as the CPU path makes it
// (sphere::MagnifyLagrange): by an integer factor, through the six nearest samples along each
// axis, longitude wrapping around the seam and the rows beyond a pole taken half a turn away;
// any other size ratio (an input narrower than the level's grid) bilinearly, as
// sphere::UpsampleBilinear (rows clamped at the poles).
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = 0) readonly buffer Source { vec4 source[]; };
layout(std430, binding = 1) writeonly buffer Target { vec4 target[]; };
#include "lighting_gate.glsl"

uniform ivec2 uSourceSize;
uniform ivec2 uTargetSize;

vec3 at(int x, int y) { return source[y * uSourceSize.x + x].rgb; }

// Row y (any integer): beyond a pole, the row next to it half a turn away.
vec3 atReflected(int x, int y) {
  int shift = 0;
  if (y < 0) {
    y = -y - 1;
    shift = uSourceSize.x / 2;
  } else if (y >= uSourceSize.y) {
    y = 2 * uSourceSize.y - y - 1;
    shift = uSourceSize.x / 2;
  }
  return at(((x + shift) % uSourceSize.x + uSourceSize.x) % uSourceSize.x, y);
}

// Lagrange weights of nodes −2 … 3 for a sample t ∈ [0, 1) past node 0.
void lagrangeWeights(float t, out float w[6]) {
  for (int j = 0; j < 6; ++j) {
    float l = 1.0;
    for (int m = 0; m < 6; ++m)
      if (m != j) l *= (t - float(m - 2)) / float(j - m);
    w[j] = l;
  }
}

void main() {
  if (gate_closed != 0u) return;
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uTargetSize.x || p.y >= uTargetSize.y) return;
  int factor = uTargetSize.x / uSourceSize.x;
  vec3 v;
  if (factor >= 1 && uTargetSize == factor * uSourceSize && uSourceSize.x % 2 == 0 && uSourceSize.x >= 6 &&
      uSourceSize.y >= 3) {
    // Output f·j + φ lies at input j + (φ + 0.5)/f − 0.5.
    vec2 x = (vec2(p % factor) + 0.5) / float(factor) - 0.5;
    ivec2 node = p / factor + ivec2(floor(x));
    float wx[6], wy[6];
    lagrangeWeights(x.x - floor(x.x), wx);
    lagrangeWeights(x.y - floor(x.y), wy);
    v = vec3(0.0);
    for (int k = 0; k < 6; ++k) {
      vec3 row = vec3(0.0);
      for (int j = 0; j < 6; ++j) row += wx[j] * atReflected(node.x - 2 + j, node.y - 2 + k);
      v += wy[k] * row;
    }
  } else {
    vec2 s = vec2(uSourceSize) / vec2(uTargetSize);
    float y = (float(p.y) + 0.5) * s.y - 0.5;
    int y0 = clamp(int(floor(y)), 0, uSourceSize.y - 1);
    int y1 = min(y0 + 1, uSourceSize.y - 1);
    float fy = clamp(y - float(y0), 0.0, 1.0);
    float xs = (float(p.x) + 0.5) * s.x - 0.5;
    int xf = int(floor(xs));
    float fx = xs - float(xf);
    int x0 = (xf % uSourceSize.x + uSourceSize.x) % uSourceSize.x;
    int x1 = (x0 + 1) % uSourceSize.x;
    v = (1.0 - fy) * ((1.0 - fx) * at(x0, y0) + fx * at(x1, y0)) + fy * ((1.0 - fx) * at(x0, y1) + fx * at(x1, y1));
  }
  target[p.y * uTargetSize.x + p.x] = vec4(v, 0.0);
}
