#version 450
// Cone tracing a batch of queries through the mipmapped volume (seed §4.3.2): the loop of
// VoxelGrid::TraceCone (see there for why the samples sit on texel centres along the dominant
// axis and how the axis opacities combine), with the texture unit filtering trilinearly within
// the sample's level (an integer lod, zero border).
layout(local_size_x = 64) in;

struct Query {
  vec4 origin_half_angle;  // xyz origin, w half-angle (radians)
  vec4 direction;          // xyz unit direction
};
layout(std430, binding = 0) readonly buffer Queries { Query queries[]; };
layout(std430, binding = 1) writeonly buffer Results { float visibility[]; };
layout(binding = 0) uniform sampler3D uVoxels;  // (occupancy, opacity x, y, z)

uniform vec3 uOrigin;  // grid minimum corner
uniform float uVoxelSize;
uniform float uSide;
uniform int uTopLevel;  // levels − 1
uniform float uStartOffset;
uniform float uStepScale;
uniform float uMaxDistance;  // 0: to the grid's exit
uniform float uOpaque;
uniform float uPartialExponent;
uniform uint uCount;

void main() {
  uint q = gl_GlobalInvocationID.x;
  if (q >= uCount) return;
  vec3 o = queries[q].origin_half_angle.xyz;
  float alpha = queries[q].origin_half_angle.w;
  vec3 dir = normalize(queries[q].direction.xyz);
  float t_enter = 0.0, t_exit = 3.0e38;
  for (int i = 0; i < 3; ++i) {
    float lo = uOrigin[i], hi = lo + uSide;
    if (dir[i] == 0.0) {
      if (o[i] < lo || o[i] > hi) t_exit = -1.0;
      continue;
    }
    float a = (lo - o[i]) / dir[i], b = (hi - o[i]) / dir[i];
    t_enter = max(t_enter, min(a, b));
    t_exit = min(t_exit, max(a, b));
  }
  vec3 ad = abs(dir);
  int m = ad.x >= ad.y && ad.x >= ad.z ? 0 : (ad.y >= ad.z ? 1 : 2);
  vec3 exponent = uPartialExponent * ad / ad[m];
  float sign_m = dir[m] > 0.0 ? 1.0 : -1.0;
  float ratio = 2.0 * tan(alpha);
  float t_end = uMaxDistance > 0.0 ? min(t_exit, uMaxDistance) : t_exit;
  float t = max(uStartOffset * uVoxelSize, t_enter);
  float occlusion = 0.0;
  while (occlusion < uOpaque) {
    float diameter = max(ratio * t, uVoxelSize);
    int level = clamp(int(floor(log2(uStepScale * diameter / uVoxelSize) + 0.5)), 0, uTopLevel);
    float ts = 0.0;
    for (;; --level) {
      float voxel = uVoxelSize * float(1 << level);
      float g = (o[m] + t * dir[m] - uOrigin[m]) / voxel - 0.5;
      float c = dir[m] > 0.0 ? ceil(g - 1.0 / 3.0) : floor(g + 1.0 / 3.0);  // see VoxelGrid
      ts = (uOrigin[m] + (c + 0.5) * voxel - o[m]) / dir[m];
      float near_face = (uOrigin[m] + (c + 0.5 - 0.5 * sign_m) * voxel - o[m]) * sign_m;
      if (level == 0 || near_face >= uVoxelSize) break;
    }
    if (!(ts < t_end)) break;
    vec3 axis_opacity = textureLod(uVoxels, (o + ts * dir - uOrigin) / uSide, float(level)).gba;
    float transmit = 1.0;
    for (int k = 0; k < 3; ++k)
      if (exponent[k] > 0.0 && axis_opacity[k] > 0.0)
        transmit *= axis_opacity[k] >= 1.0 ? 0.0 : pow(1.0 - axis_opacity[k], exponent[k]);
    occlusion += (1.0 - occlusion) * (1.0 - transmit);
    t = ts + 0.5 * uVoxelSize * float(1 << level) / ad[m];
  }
  visibility[q] = clamp(1.0 - occlusion, 0.0, 1.0);
}
