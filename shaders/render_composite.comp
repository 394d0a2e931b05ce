#version 450
#extension GL_GOOGLE_include_directive : require
// The composite of TripleProductRenderer: background × shadow ratio, then the car layer over it
// with its alpha. The background is the environment seen from the camera (a perspective
// look-up into the equirect frame, rotated into the world) or a given image of the output size.
#include "equirect.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(rgba32f, binding = 0) readonly uniform image2D uCarLayer;
layout(rgba32f, binding = 1) readonly uniform image2D uShadowLayer;
layout(rgba32f, binding = 2) writeonly uniform image2D uComposite;
layout(rgba32f, binding = 3) writeonly uniform image2D uBackgroundOut;
layout(binding = 0) uniform sampler2D uEnvironment;  // linear RGB equirect, or the background image
uniform int uBackgroundIsImage;
uniform ivec2 uSize;
uniform vec3 uCameraPosition;
uniform mat3 uWorldFromCamera;
uniform float uFocal;
uniform mat3 uEnvFromWorld;

void main() {
  ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
  if (pixel.x >= uSize.x || pixel.y >= uSize.y) return;
  vec3 background;
  if (uBackgroundIsImage != 0) {
    background = texelFetch(uEnvironment, pixel, 0).rgb;
  } else {
    vec3 dir = uWorldFromCamera * vec3((vec2(pixel) + 0.5 - 0.5 * vec2(uSize)) / uFocal, 1.0);
    ivec2 size = textureSize(uEnvironment, 0);
    vec2 uv = equirectPixel(uEnvFromWorld * dir, size) / vec2(size);
    background = textureLod(uEnvironment, uv, 0.0).rgb;
  }
  vec4 car = imageLoad(uCarLayer, pixel);
  vec3 shadow = imageLoad(uShadowLayer, pixel).rgb;
  vec3 c = mix(background * shadow, car.rgb, car.a);
  imageStore(uComposite, pixel, vec4(c, 1.0));
  imageStore(uBackgroundOut, pixel, vec4(background, 1.0));
}
