#version 450
// Stitcher, pass 0 (capture/stitcher.cpp, Stitcher::Impl::Linearize, is the CPU reference): each
// camera frame, linearized through the 256-entry sRGB table, at the level the lookup table gives
// the camera: its own pixels (level 0) or 2x2 box averages (level 1, an odd last column or row
// averaged with itself). Writes linear RGB, one vec4 per level pixel, cameras one after the other.
layout(local_size_x = 16, local_size_y = 16) in;
layout(std430, binding = 0) writeonly buffer Linear { vec4 linear[]; };
layout(std430, binding = 1) readonly buffer SrgbTable { float srgb_table[256]; };
// RGBA8 unorm, one layer per camera; texelFetch returns k / 255 exactly, which indexes the table.
layout(binding = 0) uniform sampler2DArray uImages;

uniform int uCamera;
uniform ivec2 uCamSize;    // the frame's size
uniform ivec2 uLevelSize;  // the level's size
uniform int uLevel;        // 0 or 1
uniform int uBase;         // the camera's first vec4 in `linear`

vec3 fetchLinear(int x, int y) {
  ivec3 k = ivec3(round(texelFetch(uImages, ivec3(x, y, uCamera), 0).rgb * 255.0));
  return vec3(srgb_table[k.r], srgb_table[k.g], srgb_table[k.b]);
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uLevelSize.x || p.y >= uLevelSize.y) return;
  vec3 c;
  if (uLevel == 0) {
    c = fetchLinear(p.x, p.y);
  } else {
    int x0 = 2 * p.x, x1 = min(2 * p.x + 1, uCamSize.x - 1);
    int y0 = 2 * p.y, y1 = min(2 * p.y + 1, uCamSize.y - 1);
    c = (((fetchLinear(x0, y0) + fetchLinear(x1, y0)) + fetchLinear(x0, y1)) + fetchLinear(x1, y1)) * 0.25;
  }
  linear[uBase + p.y * uLevelSize.x + p.x] = vec4(c, 0.0);
}
