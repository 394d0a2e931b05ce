#version 450
#extension GL_GOOGLE_include_directive : require
// Per-row sums of an image for the transform's decisions (constant term, mean radiance, mean
// |residue|, RMS): one work group per row, a shared-memory reduction, then
// lighting_stats_total.comp weights the rows by their solid angle in double precision.
// Row r of the output: (Σ red, Σ green, Σ blue, Σ |r|+|g|+|b|) and (Σ r²+g²+b², 0, 0, 0).
// GROUP_SIZE is set by the host per device (a power of two): see residual_transform_gpu.cpp.
#ifndef GROUP_SIZE
#define GROUP_SIZE 256
#endif
layout(local_size_x = GROUP_SIZE) in;

layout(std430, binding = 0) readonly buffer Image { vec4 pixels[]; };
layout(std430, binding = 1) writeonly buffer Rows { vec4 rows[]; };
#include "lighting_gate.glsl"

uniform ivec2 uSize;

shared vec4 s_sum[GROUP_SIZE];
shared float s_sq[GROUP_SIZE];

void main() {
  if (gate_closed != 0u) return;
  uint row = gl_WorkGroupID.x, tid = gl_LocalInvocationID.x;
  vec4 sum = vec4(0.0);
  float sq = 0.0;
  for (int col = int(tid); col < uSize.x; col += GROUP_SIZE) {
    vec3 v = pixels[int(row) * uSize.x + col].rgb;
    sum += vec4(v, abs(v.r) + abs(v.g) + abs(v.b));
    sq += dot(v, v);
  }
  s_sum[tid] = sum;
  s_sq[tid] = sq;
  barrier();
  for (uint stride = uint(GROUP_SIZE) / 2u; stride > 0u; stride >>= 1) {
    if (tid < stride) {
      s_sum[tid] += s_sum[tid + stride];
      s_sq[tid] += s_sq[tid + stride];
    }
    barrier();
  }
  if (tid == 0u) {
    rows[2u * row] = s_sum[0];
    rows[2u * row + 1u] = vec4(s_sq[0], 0.0, 0.0, 0.0);
  }
}
