// One visibility cone through the mipmapped volume: the loop of VoxelGrid::TraceCone, as in
// cone_trace.comp (see there and voxel_grid.h for why samples sit on texel centres along the
// dominant axis and how the axis opacities combine). Needs the sampler and uniforms below.
layout(binding = 0) uniform sampler3D uVoxels;  // (occupancy, opacity x, y, z)
uniform vec3 uVoxelOrigin;                      // grid minimum corner
uniform float uVoxelSize;
uniform float uVoxelSide;
uniform int uVoxelTopLevel;  // levels − 1; < 0: no volume (everything visible)
uniform float uConeStartOffset;
uniform float uConeStepScale;
uniform float uConeMaxDistance;  // 0: to the grid's exit
uniform float uConeOpaque;
uniform float uConePartialExponent;

float traceCone(vec3 o, vec3 dir, float alpha) {
  if (uVoxelTopLevel < 0) return 1.0;
  dir = normalize(dir);
  float t_enter = 0.0, t_exit = 3.0e38;
  for (int i = 0; i < 3; ++i) {
    float lo = uVoxelOrigin[i], hi = lo + uVoxelSide;
    if (dir[i] == 0.0) {
      if (o[i] < lo || o[i] > hi) t_exit = -1.0;
      continue;
    }
    float a = (lo - o[i]) / dir[i], b = (hi - o[i]) / dir[i];
    t_enter = max(t_enter, min(a, b));
    t_exit = min(t_exit, max(a, b));
  }
  if (t_exit <= t_enter) return 1.0;
  vec3 ad = abs(dir);
  int m = ad.x >= ad.y && ad.x >= ad.z ? 0 : (ad.y >= ad.z ? 1 : 2);
  vec3 exponent = uConePartialExponent * ad / ad[m];
  float sign_m = dir[m] > 0.0 ? 1.0 : -1.0;
  float ratio = 2.0 * tan(alpha);
  float t_end = uConeMaxDistance > 0.0 ? min(t_exit, uConeMaxDistance) : t_exit;
  float t = max(uConeStartOffset * uVoxelSize, t_enter);
  float occlusion = 0.0;
  while (occlusion < uConeOpaque) {
    float diameter = max(ratio * t, uVoxelSize);
    int level = clamp(int(floor(log2(uConeStepScale * diameter / uVoxelSize) + 0.5)), 0, uVoxelTopLevel);
    float ts = 0.0;
    for (;; --level) {
      float voxel = uVoxelSize * float(1 << level);
      float g = (o[m] + t * dir[m] - uVoxelOrigin[m]) / voxel - 0.5;
      float c = dir[m] > 0.0 ? ceil(g - 1.0 / 3.0) : floor(g + 1.0 / 3.0);
      ts = (uVoxelOrigin[m] + (c + 0.5) * voxel - o[m]) / dir[m];
      float near_face = (uVoxelOrigin[m] + (c + 0.5 - 0.5 * sign_m) * voxel - o[m]) * sign_m;
      if (level == 0 || near_face >= uVoxelSize) break;
    }
    if (!(ts < t_end)) break;
    vec3 axis_opacity = textureLod(uVoxels, (o + ts * dir - uVoxelOrigin) / uVoxelSide, float(level)).gba;
    float transmit = 1.0;
    for (int k = 0; k < 3; ++k)
      if (exponent[k] > 0.0 && axis_opacity[k] > 0.0)
        transmit *= axis_opacity[k] >= 1.0 ? 0.0 : pow(1.0 - axis_opacity[k], exponent[k]);
    occlusion += (1.0 - occlusion) * (1.0 - transmit);
    t = ts + 0.5 * uVoxelSize * float(1 << level) / ad[m];
  }
  return clamp(1.0 - occlusion, 0.0, 1.0);
}
