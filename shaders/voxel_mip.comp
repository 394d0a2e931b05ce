#version 450
// One 3D mip level from the one above, exactly as VoxelGrid::BuildMips does it in 8-bit
// integers: r the mean of the 2×2×2 children rounded to nearest; g, b, a the opacity along
// x, y, z: the larger opacity of each of the four pairs of children adjacent along that axis,
// the four averaged (voxel_grid.h says why).
layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;

layout(rgba8, binding = 0) readonly uniform image3D uSource;
layout(rgba8, binding = 1) writeonly uniform image3D uTarget;

uniform int uSize;  // of the target level

void main() {
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, ivec3(uSize)))) return;
  ivec4 child[8];
  int sum = 0;
  for (int c = 0; c < 8; ++c) {
    child[c] = ivec4(round(imageLoad(uSource, 2 * p + ivec3(c & 1, (c >> 1) & 1, c >> 2)) * 255.0));
    sum += child[c].r;
  }
  ivec3 pairs = ivec3(0);
  for (int k = 0; k < 3; ++k) {
    int bit = 1 << k;
    for (int c = 0; c < 8; ++c) {
      if ((c & bit) != 0) continue;
      pairs[k] += max(child[c][k + 1], child[c | bit][k + 1]);
    }
  }
  imageStore(uTarget, p, vec4((sum + 4) / 8, (pairs + 2) / 4) / 255.0);
}
