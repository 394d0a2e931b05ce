#version 450
// RenderOptions::supersample: the car and shadow layers, shaded at k× the output size, resolved
// to it with Cycles' default pixel filter. The CPU reference is detail::ResolveSupersampled
// (triple_product_reference.cpp), which sums in the same order; the weights are its table.
layout(local_size_x = 8, local_size_y = 8) in;

layout(rgba32f, binding = 0) readonly uniform image2D uShadedCar;
layout(rgba32f, binding = 1) readonly uniform image2D uShadedShadow;
layout(rgba32f, binding = 2) writeonly uniform image2D uCarLayer;
layout(rgba32f, binding = 3) writeonly uniform image2D uShadowLayer;
uniform ivec2 uSize;        // output
uniform ivec2 uShadedSize;  // k× the output
uniform int uFactor;        // k
uniform float uWeights[12];  // 3k entries: sample offset j − k of the output pixel's k·X
// RenderOptions::supersample_contrast > 0: a pixel render_flag.comp did not flag had only its
// sample nearest the centre shaded, which then stands for each of its samples.
uniform int uAdaptive;
layout(std430, binding = 9) readonly buffer PixelFlags { uint pixelFlags[]; };

ivec2 shadedSample(ivec2 s) {
  if (uAdaptive == 0) return s;
  ivec2 p = s / uFactor;
  return pixelFlags[p.y * uSize.x + p.x] != 0u ? s : p * uFactor + uFactor / 2;
}

void main() {
  ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
  if (pixel.x >= uSize.x || pixel.y >= uSize.y) return;
  float wSum = 0.0, alpha = 0.0, ground = 0.0, uncovered = 0.0;
  vec3 car = vec3(0.0), shadow = vec3(0.0);
  for (int j = 0; j < 3 * uFactor; ++j) {
    int y = uFactor * pixel.y - uFactor + j;
    if (y < 0 || y >= uShadedSize.y || uWeights[j] == 0.0) continue;
    for (int i = 0; i < 3 * uFactor; ++i) {
      int x = uFactor * pixel.x - uFactor + i;
      if (x < 0 || x >= uShadedSize.x || uWeights[i] == 0.0) continue;
      float w = uWeights[j] * uWeights[i];
      ivec2 sample_ = shadedSample(ivec2(x, y));
      vec4 c = imageLoad(uShadedCar, sample_);
      vec4 s = imageLoad(uShadedShadow, sample_);
      wSum += w;
      alpha += w * c.a;
      ground += w * s.a;
      uncovered += w * (1.0 - c.a);
      car += w * c.a * c.rgb;
      shadow += w * (1.0 - c.a) * s.rgb;
    }
  }
  if (alpha > 0.0) car /= alpha;
  shadow = uncovered > 0.0 ? shadow / uncovered : vec3(1.0);
  imageStore(uCarLayer, pixel, vec4(car, alpha / wSum));
  imageStore(uShadowLayer, pixel, vec4(shadow, ground / wSum));
}
