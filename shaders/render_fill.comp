#version 450
// RenderOptions::shading_rate 2: the pixels render_shade.comp left unshaded. In a block that
// render_flag.comp did not flag only the lower-right pixel (2b + 1) was shaded; a pixel at an
// even offset lies midway between that pixel and its left (upper) neighbour block's, so it takes
// the mean of the two (four for the upper-left pixel), radiance, coverage, shadow ratio and ground
// mask alike. A flagged block had every pixel shaded. The CPU reference is
// detail::FillHalfRate (triple_product_reference.cpp).
layout(local_size_x = 8, local_size_y = 8) in;

layout(rgba32f, binding = 0) uniform image2D uCar;     // rgb radiance, coverage
layout(rgba32f, binding = 1) uniform image2D uShadow;  // rgb ratio, ground mask
layout(std430, binding = 9) readonly buffer BlockFlags { uint blockFlags[]; };

uniform ivec2 uSize;    // pixels
uniform ivec2 uBlocks;  // ceil(uSize / 2); a block cut by an odd edge is flagged, so shaded whole

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  ivec2 b = p / 2, o = p - 2 * b;
  if (o == ivec2(1) || blockFlags[b.y * uBlocks.x + b.x] != 0u) return;
  // Reads only shaded pixels (odd coordinates), writes only unshaded ones: no pixel is both.
  ivec2 lo = 2 * (b - ivec2(1) + o) + 1, hi = 2 * b + 1;
  vec4 car = 0.25 * (imageLoad(uCar, lo) + imageLoad(uCar, ivec2(hi.x, lo.y)) + imageLoad(uCar, ivec2(lo.x, hi.y)) +
                     imageLoad(uCar, hi));
  vec4 shadow = 0.25 * (imageLoad(uShadow, lo) + imageLoad(uShadow, ivec2(hi.x, lo.y)) +
                        imageLoad(uShadow, ivec2(lo.x, hi.y)) + imageLoad(uShadow, hi));
  imageStore(uCar, p, car);
  imageStore(uShadow, p, shadow);
}
