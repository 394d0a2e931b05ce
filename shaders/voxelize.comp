#version 450
// Conservative voxelization, one invocation per triangle (engine/visibility/voxelizer_gpu.h):
// the triangle's dominant axis picks the column direction, and each column of its footprint
// runs the exact triangle–box overlap test (Akenine-Möller) on the ≤ 3 voxels the plane
// crosses there. The same walk and test as VoxelGrid::Voxelize, so both mark the same voxels.
layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Vertices { vec4 vertices[]; };  // 3 per triangle
// (occupancy, opacity along x, y, z): all four are the occupancy at level 0.
layout(rgba8, binding = 0) writeonly uniform image3D uVoxels;

uniform vec3 uOrigin;
uniform float uInvVoxel;  // 1 / voxel size
uniform int uResolution;
uniform uint uTriangles;

// Touching counts as overlapping (strict comparisons for separation), as on the CPU.
bool Overlaps(vec3 a, vec3 b, vec3 c, vec3 centre) {
  const float h = 0.5;
  vec3 v0 = a - centre, v1 = b - centre, v2 = c - centre;
  vec3 e[3] = vec3[3](v1 - v0, v2 - v1, v0 - v2);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      vec3 axis = vec3(0.0);
      axis[(i + 1) % 3] = -e[j][(i + 2) % 3];
      axis[(i + 2) % 3] = e[j][(i + 1) % 3];
      float p0 = dot(axis, v0), p1 = dot(axis, v1), p2 = dot(axis, v2);
      float r = h * (abs(axis.x) + abs(axis.y) + abs(axis.z));
      if (min(p0, min(p1, p2)) > r || max(p0, max(p1, p2)) < -r) return false;
    }
  }
  vec3 lo = min(v0, min(v1, v2)), hi = max(v0, max(v1, v2));
  if (any(greaterThan(lo, vec3(h))) || any(lessThan(hi, vec3(-h)))) return false;
  vec3 n = cross(e[0], e[1]);
  return abs(dot(n, v0)) <= h * (abs(n.x) + abs(n.y) + abs(n.z));
}

void main() {
  uint t = gl_GlobalInvocationID.x;
  if (t >= uTriangles) return;
  vec3 q[3];
  for (int k = 0; k < 3; ++k) q[k] = (vertices[3 * t + uint(k)].xyz - uOrigin) * uInvVoxel;
  if (any(isnan(q[0])) || any(isnan(q[1])) || any(isnan(q[2])) || any(isinf(q[0])) || any(isinf(q[1])) ||
      any(isinf(q[2])))
    return;
  vec3 lo = min(q[0], min(q[1], q[2])), hi = max(q[0], max(q[1], q[2]));
  float res = float(uResolution);
  if (any(greaterThan(lo, vec3(res))) || any(lessThan(hi, vec3(0.0)))) return;
  ivec3 first = ivec3(max(vec3(0.0), ceil(lo) - 1.0));
  ivec3 last = ivec3(min(vec3(res - 1.0), floor(hi)));
  if (any(greaterThan(first, last))) return;

  vec3 n = cross(q[1] - q[0], q[2] - q[0]);
  vec3 an = abs(n);
  int w = an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2);
  int u = (w + 1) % 3, v = (w + 2) % 3;
  float d = dot(n, q[0]);
  for (int i = first[u]; i <= last[u]; ++i) {
    for (int j = first[v]; j <= last[v]; ++j) {
      int k0 = first[w], k1 = last[w];
      if (an[w] > 0.0) {
        float wc = (d - n[u] * (float(i) + 0.5) - n[v] * (float(j) + 0.5)) / n[w];
        float half_range = 0.5 * (an[u] + an[v]) / an[w] + 1e-3;
        k0 = max(k0, int(ceil(wc - half_range)) - 1);
        k1 = min(k1, int(floor(wc + half_range)));
      }
      for (int k = k0; k <= k1; ++k) {
        ivec3 c;
        c[u] = i;
        c[v] = j;
        c[w] = k;
        // Racing stores all write the same value, so no atomics are needed.
        if (Overlaps(q[0], q[1], q[2], vec3(c) + 0.5)) imageStore(uVoxels, c, vec4(1.0));
      }
    }
  }
}
