#version 450
// The second shading pass's size from the flagged list's count (render_flag.comp), written as the
// arguments of glDispatchComputeIndirect, so that the CPU need not wait for the flags to read the
// count: count × (k² − 1) invocations in rows of uListPitch, render_shade.comp's 8 × 8 groups (its
// lanes run within a group along z).
layout(local_size_x = 1) in;

layout(std430, binding = 10) readonly buffer FlaggedList { uint flaggedCount; };
layout(std430, binding = 13) writeonly buffer DispatchArgs { uvec3 groups; };

uniform int uFactor;     // k
uniform int uListPitch;  // a multiple of 8

void main() {
  uint samples = flaggedCount * uint(uFactor * uFactor - 1);
  uint rows = (samples + uint(uListPitch) - 1u) / uint(uListPitch);
  groups = uvec3(uint(uListPitch) / 8u, (rows + 7u) / 8u, 1u);
}
