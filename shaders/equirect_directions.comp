#version 450
#extension GL_GOOGLE_include_directive : require
// Per pixel of a W x H equirectangular image: its unit direction (xyz) and solid angle (w).
// The lighting transform reads this table instead of re-evaluating trigonometry per level.
#include "equirect.glsl"

layout(local_size_x = 16, local_size_y = 16) in;
layout(std430, binding = 0) writeonly buffer Directions { vec4 directions[]; };
uniform ivec2 uSize;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  vec3 d = equirectDirection(vec2(p) + 0.5, uSize);
  directions[p.y * uSize.x + p.x] = vec4(d, equirectPixelSolidAngle(p.y, uSize));
}
