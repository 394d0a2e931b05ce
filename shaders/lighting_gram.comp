#version 450
#extension GL_GOOGLE_include_directive : require
// A refitting sweep of the residual transform on a level's amplitudes (LevelGram in
// residual_transform.h): P(r − R(μ)) = P(r) − Mμ, with M the level's projection of its own
// reconstruction, so a sweep is μ' = μ + uStep (P(r) − Mμ), one invocation per SRBF over its row
// of M, instead of a reconstruction and a projection of the whole grid. `projected` holds P(r),
// the level's first projection; μ' goes to another buffer (every row reads all of μ).
layout(local_size_x = 64) in;

struct Entry {
  int column;
  float value;
};

layout(std430, binding = 0) readonly buffer Projected { vec4 projected[]; };
layout(std430, binding = 1) readonly buffer GramBegin { int gram_begin[]; };
layout(std430, binding = 2) readonly buffer GramEntries { Entry gram_entries[]; };
layout(std430, binding = 3) readonly buffer MuIn { vec4 mu_in[]; };
layout(std430, binding = 4) writeonly buffer MuOut { vec4 mu_out[]; };
#include "lighting_gate.glsl"

uniform int uCount;
uniform float uStep;

void main() {
  if (gate_closed != 0u) return;
  int c = int(gl_GlobalInvocationID.x);
  if (c >= uCount) return;
  vec3 sum = vec3(0.0);
  for (int k = gram_begin[c]; k < gram_begin[c + 1]; ++k) {
    Entry e = gram_entries[k];
    sum += e.value * mu_in[e.column].rgb;
  }
  mu_out[c] = vec4(mu_in[c].rgb + uStep * (projected[c].rgb - sum), 0.0);
}
