#version 450
// Area resampling of an equirect image to a working grid of the residual transform: the 2D form
// of sphere::ResampleArea (a box filter with fractional coverage, each source row weighted by its
// coverage times its solid angle: the mean of every output pixel's footprint on the sphere), so
// the GPU and CPU grids hold the same values. Defining SOURCE_TEXTURE reads the frame itself from
// a texture (texel row 0 = the top row, as it was uploaded) and clamps NaN, Inf and negative
// channels to 0 on the way in, counting the pixels once each.
layout(local_size_x = 16, local_size_y = 16) in;

#ifdef SOURCE_TEXTURE
layout(binding = 0) uniform sampler2D uSource;
layout(std430, binding = 2) buffer Counters { uint bad_pixels; uint negative_pixels; };
#else
layout(std430, binding = 0) readonly buffer Source { vec4 source[]; };
#endif
layout(std430, binding = 1) writeonly buffer Target { vec4 target[]; };

uniform ivec2 uSourceSize;
const float kPi = 3.14159265358979323846;
uniform ivec2 uTargetSize;

vec3 fetchSource(int x, int y, bool count) {
#ifdef SOURCE_TEXTURE
  vec3 v = texelFetch(uSource, ivec2(x, y), 0).rgb;
  // Bit tests, not comparisons: a compiler may fold !(v >= 0) into v < 0, which lets NaN through.
  bool bad = false, negative = false;
  for (int k = 0; k < 3; ++k) {
    uint bits = floatBitsToUint(v[k]);
    if ((bits & 0x7f800000u) == 0x7f800000u) {
      bad = true;
      v[k] = 0.0;
    } else if ((bits & 0x80000000u) != 0u) {
      if ((bits & 0x7fffffffu) != 0u) negative = true;
      v[k] = 0.0;
    }
  }
  if (count && bad) atomicAdd(bad_pixels, 1u);
  if (count && negative && !bad) atomicAdd(negative_pixels, 1u);
  return v;
#else
  return source[y * uSourceSize.x + x].rgb;
#endif
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uTargetSize.x || p.y >= uTargetSize.y) return;
  vec2 s = vec2(uSourceSize) / vec2(uTargetSize);
  vec2 lo = vec2(p) * s, hi = vec2(p + 1) * s;
  int x_end = min(int(ceil(hi.x)), uSourceSize.x), y_end = min(int(ceil(hi.y)), uSourceSize.y);
  vec3 acc = vec3(0.0);
  float row_weights = 0.0;
  for (int y = int(floor(lo.y)); y < y_end; ++y) {
    // The area of the part of row y's latitude band inside the target row's, per radian of
    // longitude: cos θ0 − cos θ1 as a product of sines, accurate for thin bands in float.
    float a = kPi * max(float(y), lo.y) / float(uSourceSize.y), b = kPi * min(float(y + 1), hi.y) / float(uSourceSize.y);
    float wy = 2.0 * sin(0.5 * (a + b)) * sin(0.5 * (b - a));
    row_weights += wy;
    vec3 row = vec3(0.0);
    for (int x = int(floor(lo.x)); x < x_end; ++x) {
      float wx = min(float(x + 1), hi.x) - max(float(x), lo.x);
      // Each source pixel is counted by the one output whose footprint holds its corner.
      row += wx * fetchSource(x, y, float(x) >= lo.x && float(y) >= lo.y);
    }
    acc += wy * row;
  }
  target[p.y * uTargetSize.x + p.x] = vec4(acc / (s.x * row_weights), 0.0);
}
