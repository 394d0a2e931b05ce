#version 450
#extension GL_GOOGLE_include_directive : require
// The equirectangular frame seen from its centre: each pixel's ray, through the inverse
// view-projection, looks the panorama up with odvr's one convention (equirect.glsl).
#include "equirect.glsl"

in vec2 vNdc;
layout(location = 0) out vec4 fragColor;
layout(binding = 0) uniform sampler2D uPanorama;  // linear RGB
uniform mat4 uWorldFromClip;                      // inverse(projection * rotation-only view)
uniform float uExposure;
uniform int uEncodeSrgb;

vec3 encodeSrgb(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}

void main() {
  vec4 far = uWorldFromClip * vec4(vNdc, 1.0, 1.0);
  vec3 dir = normalize(far.xyz / far.w);
  ivec2 size = textureSize(uPanorama, 0);
  vec2 uv = equirectPixel(dir, size) / vec2(size);
  // Level 0 explicitly: the uv jump at the seam would otherwise pick a tiny mip there.
  vec3 c = textureLod(uPanorama, uv, 0.0).rgb * uExposure;
  fragColor = vec4(uEncodeSrgb != 0 ? encodeSrgb(c) : c, 1.0);
}
