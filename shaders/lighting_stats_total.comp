#version 450
#extension GL_GOOGLE_include_directive : require
// Sums the per-row results of lighting_stats.comp, each weighted by its row's solid angle, in
// double precision (one work group), into slot uSlot of the totals the CPU reads back:
// (Σ r dA, Σ g dA, Σ b dA, Σ (|r|+|g|+|b|) dA, Σ (r²+g²+b²) dA).
// GROUP_SIZE is set by the host per device (a power of two): see residual_transform_gpu.cpp.
#ifndef GROUP_SIZE
#define GROUP_SIZE 256
#endif
layout(local_size_x = GROUP_SIZE) in;

layout(std430, binding = 0) readonly buffer Rows { vec4 rows[]; };
layout(std430, binding = 1) readonly buffer RowSolidAngle { double row_solid_angle[]; };
layout(std430, binding = 2) buffer Totals { double totals[]; };
#include "lighting_gate.glsl"

uniform int uRows;
uniform int uSlot;

shared double s_acc[5][GROUP_SIZE];

void main() {
  if (gate_closed != 0u) return;
  uint tid = gl_LocalInvocationID.x;
  double acc[5] = double[5](0.0LF, 0.0LF, 0.0LF, 0.0LF, 0.0LF);
  for (int row = int(tid); row < uRows; row += GROUP_SIZE) {
    double da = row_solid_angle[row];
    vec4 sum = rows[2 * row];
    for (int k = 0; k < 4; ++k) acc[k] += double(sum[k]) * da;
    acc[4] += double(rows[2 * row + 1].x) * da;
  }
  for (int k = 0; k < 5; ++k) s_acc[k][tid] = acc[k];
  barrier();
  for (uint stride = uint(GROUP_SIZE) / 2u; stride > 0u; stride >>= 1) {
    if (tid < stride)
      for (int k = 0; k < 5; ++k) s_acc[k][tid] += s_acc[k][tid + stride];
    barrier();
  }
  if (tid == 0u)
    for (int k = 0; k < 5; ++k) totals[8 * uSlot + k] = s_acc[k][0];
}
