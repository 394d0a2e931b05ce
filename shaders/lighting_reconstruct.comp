#version 450
#extension GL_GOOGLE_include_directive : require
// Pass 2 of a level of the residual transform (seed Algorithm 3, eq. 4.18), one invocation per
// pixel over its precomputed SRBF list: out = base + uSign · Σ_c μ_c G_c(ω).
// Used three ways: the residue a level leaves (base = residue, sign −1); the reconstruction of
// everything fitted so far on a finer grid (base = out = the magnified reconstruction, sign +1,
// with uWriteResidue also writing target − out, the next level's residue). uUseLists = 0 adds
// nothing (level 0: the reconstruction is the constant term).
layout(local_size_x = 256) in;

struct Entry {
  int srbf;
  float g;
};

layout(std430, binding = 0) readonly buffer Base { vec4 base[]; };
layout(std430, binding = 1) buffer Out { vec4 out_pixels[]; };
layout(std430, binding = 2) readonly buffer PixelBegin { int pixel_begin[]; };
layout(std430, binding = 3) readonly buffer PixelEntries { Entry pixel_entries[]; };
layout(std430, binding = 4) readonly buffer Mu { vec4 mu[]; };
layout(std430, binding = 5) readonly buffer Target { vec4 target[]; };
layout(std430, binding = 6) writeonly buffer Residue { vec4 residue[]; };
#include "lighting_gate.glsl"

uniform int uCount;
uniform float uSign;
uniform int uUseLists;
uniform int uWriteResidue;

void main() {
  if (gate_closed != 0u) return;
  int p = int(gl_GlobalInvocationID.x);
  if (p >= uCount) return;
  vec3 acc = vec3(0.0);
  if (uUseLists != 0) {
    int end = pixel_begin[p + 1];
    for (int e = pixel_begin[p]; e < end; ++e) {
      Entry entry = pixel_entries[e];
      acc += mu[entry.srbf].rgb * entry.g;
    }
  }
  vec3 v = base[p].rgb + uSign * acc;
  out_pixels[p] = vec4(v, 0.0);
  if (uWriteResidue != 0) residue[p] = vec4(target[p].rgb - v, 0.0);
}
