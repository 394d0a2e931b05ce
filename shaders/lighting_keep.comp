#version 450
#extension GL_GOOGLE_include_directive : require
// The keep rule of the residual transform: an SRBF whose largest |μ| channel is below uKeep
// (keep threshold × mean radiance) is dropped (μ = 0). Counts the kept SRBFs in the level's slot
// of the flags, which the CPU reads for every level at once.
layout(local_size_x = 64) in;

layout(std430, binding = 0) buffer Mu { vec4 mu[]; };
layout(std430, binding = 1) buffer Flags { uint flags[]; };  // per level: SRBFs kept
#include "lighting_gate.glsl"

uniform int uCount;
uniform float uKeep;
uniform int uFlagsSlot;

void main() {
  if (gate_closed != 0u) return;
  int c = int(gl_GlobalInvocationID.x);
  if (c >= uCount) return;
  vec3 m = mu[c].rgb;
  if (max(abs(m.r), max(abs(m.g), abs(m.b))) < uKeep) {
    mu[c] = vec4(0.0);
  } else {
    atomicAdd(flags[uFlagsSlot], 1u);
  }
}
