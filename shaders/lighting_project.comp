#version 450
#extension GL_GOOGLE_include_directive : require
// Pass 1 of a level of the residual transform (seed Algorithm 2, eq. 4.17): one work group per
// SRBF c gathers μ_c = scale_c · Σ_{ω∈R(c)} w(ω) r(ω) over its precomputed pixel list, each
// invocation striding through the list and a shared-memory tree adding the partial sums.
// w is G·dA or the partition weight G·dA/S and scale_c 1/Σ G·dA (divided by S̄_c for the
// local-sum normalization), both from the CPU's LevelTables. uAccumulate adds the result to μ
// (the refit sweeps: μ += uStep · projection of what the level left; uStep over-relaxes them at
// the fine levels, see ResidualTransformOptions::fine_relaxation).
// GROUP_SIZE is set by the host per device (a power of two): see residual_transform_gpu.cpp.
#ifndef GROUP_SIZE
#define GROUP_SIZE 64
#endif
layout(local_size_x = GROUP_SIZE) in;

struct Entry {
  int pixel;
  float weight;
};

layout(std430, binding = 0) readonly buffer Residue { vec4 residue[]; };
layout(std430, binding = 1) readonly buffer SrbfBegin { int srbf_begin[]; };
layout(std430, binding = 2) readonly buffer SrbfEntries { Entry srbf_entries[]; };
layout(std430, binding = 3) readonly buffer SrbfScale { float srbf_scale[]; };
layout(std430, binding = 4) buffer Mu { vec4 mu[]; };
#include "lighting_gate.glsl"

uniform int uAccumulate;
uniform float uStep;

shared vec3 s_partial[GROUP_SIZE];

void main() {
  if (gate_closed != 0u) return;
  uint c = gl_WorkGroupID.x, tid = gl_LocalInvocationID.x;
  int end = srbf_begin[c + 1u];
  vec3 acc = vec3(0.0);
  for (int e = srbf_begin[c] + int(tid); e < end; e += GROUP_SIZE) {
    Entry entry = srbf_entries[e];
    acc += entry.weight * residue[entry.pixel].rgb;
  }
  s_partial[tid] = acc;
  barrier();
  for (uint stride = uint(GROUP_SIZE) / 2u; stride > 0u; stride >>= 1) {
    if (tid < stride) s_partial[tid] += s_partial[tid + stride];
    barrier();
  }
  if (tid == 0u) {
    vec3 m = s_partial[0] * srbf_scale[c];
    mu[c] = vec4(uAccumulate != 0 ? mu[c].rgb + uStep * m : m, 0.0);
  }
}
