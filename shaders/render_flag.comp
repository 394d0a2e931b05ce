#version 450
// RenderOptions::supersample_contrast: which pixels get every one of their k×k samples shaded.
// Only the sample nearest each pixel's centre (k/2, k/2) is shaded first; a pixel is flagged
// where its samples see different surfaces (coverage or material differ, or the shading normal
// turns by more than uNormalCos) or where the shaded samples' car luminance bends across it:
// |Y(−d) + Y(+d) − 2 Y(0)| > uContrast · max of the three, along a row, a column or a diagonal
// (neighbouring pixels' samples), or the shadow ratio (0..1) bends by more than uContrast. A
// linear change within a pixel averages to its centre's value; what one sample misses is the
// curvature. RenderOptions::shading_rate 2 uses the same tests with k = 2 over 2×2 blocks of the
// output (uNeighbourReps): render_fill.comp then fills an unflagged block's pixels from its own
// and its left, upper and upper-left neighbours' shaded pixels, so a block is flagged too where
// one of those sees another surface, and on the top and left edges, which lack them. The CPU
// reference is detail::FlagPixels (triple_product_reference.cpp).
layout(local_size_x = 8, local_size_y = 8) in;

layout(rgba32f, binding = 0) readonly uniform image2D uGPosition;  // k× the output: xyz, material + 1
layout(rgba32f, binding = 1) readonly uniform image2D uGNormal;
layout(rgba32f, binding = 2) readonly uniform image2D uShadedCar;
layout(rgba32f, binding = 3) readonly uniform image2D uShadedShadow;
layout(std430, binding = 9) writeonly buffer PixelFlags { uint pixelFlags[]; };
// The flagged pixels, listed for render_shade.comp's second pass (any order: each sample writes
// only its own texel and counts).
layout(std430, binding = 10) buffer FlaggedList {
  uint flaggedCount;
  uint flagged[];
};
uniform ivec2 uSize;  // output
uniform int uFactor;  // k
uniform float uContrast;
uniform float uNormalCos;
uniform int uNeighbourReps;

const vec3 kLuma = vec3(0.2126, 0.7152, 0.0722);

float carLuma(ivec2 pixel) { return dot(imageLoad(uShadedCar, pixel * uFactor + uFactor / 2).rgb, kLuma); }
float shadowLuma(ivec2 pixel) { return dot(imageLoad(uShadedShadow, pixel * uFactor + uFactor / 2).rgb, kLuma); }

void main() {
  ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
  if (pixel.x >= uSize.x || pixel.y >= uSize.y) return;
  ivec2 centre = pixel * uFactor + uFactor / 2;
  uint index = uint(pixel.y * uSize.x + pixel.x);
  // A block cut by the right or bottom edge of an odd-sized output (shading_rate 2): shaded whole.
  if (any(greaterThanEqual(pixel * uFactor + uFactor - 1, imageSize(uGPosition)))) {
    pixelFlags[index] = 1u;
    flagged[atomicAdd(flaggedCount, 1u)] = index;
    return;
  }
  vec4 g = imageLoad(uGPosition, centre);
  vec3 n = imageLoad(uGNormal, centre).xyz;
  bool flag = false;
  for (int y = 0; y < uFactor; ++y)
    for (int x = 0; x < uFactor; ++x) {
      ivec2 s = pixel * uFactor + ivec2(x, y);
      vec4 gs = imageLoad(uGPosition, s);
      if (gs.w != g.w || (g.w > 0.0 && dot(imageLoad(uGNormal, s).xyz, n) < uNormalCos)) flag = true;
    }
  if (uNeighbourReps != 0) {
    if (pixel.x == 0 || pixel.y == 0) flag = true;
    for (int i = 1; i < 4 && !flag; ++i) {
      ivec2 s = centre - uFactor * ivec2(i & 1, i >> 1);
      vec4 gs = imageLoad(uGPosition, s);
      if (gs.w != g.w || (g.w > 0.0 && dot(imageLoad(uGNormal, s).xyz, n) < uNormalCos)) flag = true;
    }
  }
  float car = carLuma(pixel), shadow = shadowLuma(pixel);
  const ivec2 kDirections[4] = ivec2[4](ivec2(1, 0), ivec2(0, 1), ivec2(1, 1), ivec2(1, -1));
  for (int i = 0; i < 4; ++i) {
    ivec2 a = pixel - kDirections[i], b = pixel + kDirections[i];
    if (min(min(a.x, a.y), min(b.x, b.y)) < 0 || max(a.x, b.x) >= uSize.x || max(a.y, b.y) >= uSize.y) continue;
    if (any(greaterThanEqual(max(a, b) * uFactor + uFactor / 2, imageSize(uGPosition)))) continue;
    float ca = carLuma(a), cb = carLuma(b);
    if (abs(ca + cb - 2.0 * car) > uContrast * max(car, max(ca, cb)) ||
        abs(shadowLuma(a) + shadowLuma(b) - 2.0 * shadow) > uContrast)
      flag = true;
  }
  pixelFlags[index] = flag ? 1u : 0u;
  if (flag) flagged[atomicAdd(flaggedCount, 1u)] = index;
}
