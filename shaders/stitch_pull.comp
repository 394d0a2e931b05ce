#version 450
// Pull-push fill, pull: each coarse pixel averages its (up to) 2x2 children, premultiplied
// colour and coverage alike; columns wrap around the equirect seam. CPU reference: Pull() in
// capture/stitcher.cpp.
layout(local_size_x = 16, local_size_y = 16) in;
layout(std430, binding = 0) readonly buffer Fine { vec4 fine[]; };
layout(std430, binding = 1) writeonly buffer Coarse { vec4 coarse[]; };
uniform ivec2 uFineSize;
uniform ivec2 uCoarseSize;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uCoarseSize.x || p.y >= uCoarseSize.y) return;
  vec4 sum = vec4(0.0);
  int n = 0;
  for (int dy = 0; dy < 2; ++dy) {
    int fy = 2 * p.y + dy;
    if (fy >= uFineSize.y) continue;
    for (int dx = 0; dx < 2; ++dx) {
      int fx = (2 * p.x + dx) % uFineSize.x;
      sum += fine[fy * uFineSize.x + fx];
      ++n;
    }
  }
  coarse[p.y * uCoarseSize.x + p.x] = sum / float(n);
}
