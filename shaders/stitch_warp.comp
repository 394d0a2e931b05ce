#version 450
// Stitcher, pass 1 (capture/stitcher.cpp is the CPU reference): per output equirect pixel, the
// lookup-table entries (camera, pixel, feather weight) are sampled bilinearly from the
// linearized camera frames at the camera's level (stitch_linearize.comp), scaled by the camera's
// gain and blended by weight. Writes linear RGB and coverage (1 = some camera in use saw it,
// 0 = unseen) for the pull-push fill.
layout(local_size_x = 16, local_size_y = 16) in;

struct Entry {
  float u;
  float v;
  float weight;
  uint camera;
};
layout(std430, binding = 0) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = 1) readonly buffer Entries { Entry entries[]; };
layout(std430, binding = 2) writeonly buffer Out { vec4 outp[]; };
layout(std430, binding = 3) readonly buffer Linear { vec4 linear[]; };

uniform ivec2 uSize;
uniform float uGain[32];  // 0 for cameras left out (missing or black frames)
uniform ivec2 uLevelSize[32];
uniform int uLevel[32];
uniform int uBase[32];

vec3 fetchLinear(int cam, int x, int y) { return linear[uBase[cam] + y * uLevelSize[cam].x + x].rgb; }

// Same expression as SampleTap in stitcher.cpp: OpenCV pixel centres at integers, edges clamped
// (the CPU gets the clamp by a zero fraction), full-image coordinates mapped to the level by
// (u - 0.5) / 2, exactly in float.
vec3 sampleBilinear(int cam, float u, float v) {
  if (uLevel[cam] != 0) {
    u = (u - 0.5) * 0.5;
    v = (v - 0.5) * 0.5;
  }
  ivec2 size = uLevelSize[cam];
  float fu = floor(u), fv = floor(v);
  float au = u - fu, av = v - fv;
  int x0 = clamp(int(fu), 0, size.x - 1), x1 = clamp(int(fu) + 1, 0, size.x - 1);
  int y0 = clamp(int(fv), 0, size.y - 1), y1 = clamp(int(fv) + 1, 0, size.y - 1);
  vec3 p00 = fetchLinear(cam, x0, y0), p10 = fetchLinear(cam, x1, y0);
  vec3 p01 = fetchLinear(cam, x0, y1), p11 = fetchLinear(cam, x1, y1);
  vec3 top = p00 + au * (p10 - p00);
  vec3 bottom = p01 + au * (p11 - p01);
  return top + av * (bottom - top);
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint pixel = uint(p.y * uSize.x + p.x);
  vec3 acc = vec3(0.0);
  float wsum = 0.0;
  for (uint e = offsets[pixel]; e < offsets[pixel + 1u]; ++e) {
    Entry entry = entries[e];
    int cam = int(entry.camera);
    float g = uGain[cam];
    if (g == 0.0) continue;
    acc += (entry.weight * g) * sampleBilinear(cam, entry.u, entry.v);
    wsum += entry.weight;
  }
  outp[pixel] = wsum > 0.0 ? vec4(acc / wsum, 1.0) : vec4(0.0);
}
