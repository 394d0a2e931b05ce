#version 450
// Pull-push fill, push: a level's filled colour is its own premultiplied colour plus, for the
// coverage it lacks, the coarser level's filled colour upsampled bilinearly (longitude wraps,
// latitude clamps). Alpha keeps the level's own coverage, so level 0 carries the validity mask.
// CPU reference: FillUnseen() in capture/stitcher.cpp.
layout(local_size_x = 16, local_size_y = 16) in;
layout(std430, binding = 0) readonly buffer Own { vec4 own[]; };
layout(std430, binding = 1) readonly buffer CoarseFilled { vec4 coarse[]; };
layout(std430, binding = 2) writeonly buffer Filled { vec4 filled[]; };
uniform ivec2 uSize;
uniform ivec2 uCoarseSize;
uniform int uCoarsePremultiplied;  // the 1x1 top of the pyramid is still premultiplied

vec3 coarseColour(int x, int y) {
  vec4 c = coarse[y * uCoarseSize.x + x];
  if (uCoarsePremultiplied != 0) return c.a > 0.0 ? c.rgb / c.a : vec3(0.0);
  return c.rgb;
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  float sx = (float(p.x) + 0.5) * 0.5 - 0.5, sy = (float(p.y) + 0.5) * 0.5 - 0.5;
  float fx = floor(sx), fy = floor(sy);
  float ax = sx - fx, ay = sy - fy;
  int w = uCoarseSize.x, h = uCoarseSize.y;
  // fx >= -1, and GLSL leaves % of a negative operand undefined: wrap by hand.
  int x0 = int(fx) < 0 ? int(fx) + w : int(fx) % w, x1 = (x0 + 1) % w;
  int y0 = clamp(int(fy), 0, h - 1), y1 = clamp(int(fy) + 1, 0, h - 1);
  vec3 c00 = coarseColour(x0, y0), c10 = coarseColour(x1, y0);
  vec3 c01 = coarseColour(x0, y1), c11 = coarseColour(x1, y1);
  vec3 top = c00 + ax * (c10 - c00);
  vec3 bottom = c01 + ax * (c11 - c01);
  vec3 up = top + ay * (bottom - top);
  vec4 o = own[p.y * uSize.x + p.x];
  filled[p.y * uSize.x + p.x] = vec4(o.rgb + (1.0 - o.a) * up, o.a);
}
