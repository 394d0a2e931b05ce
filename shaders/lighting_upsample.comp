#version 450
// Bilinear magnification of the reconstruction to the next level's grid, as
// sphere::UpsampleBilinear: longitude wraps around the seam, rows clamp at the poles.
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = 0) readonly buffer Source { vec4 source[]; };
layout(std430, binding = 1) writeonly buffer Target { vec4 target[]; };

uniform ivec2 uSourceSize;
uniform ivec2 uTargetSize;

vec3 at(int x, int y) { return source[y * uSourceSize.x + x].rgb; }

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uTargetSize.x || p.y >= uTargetSize.y) return;
  vec2 s = vec2(uSourceSize) / vec2(uTargetSize);
  float y = (float(p.y) + 0.5) * s.y - 0.5;
  int y0 = clamp(int(floor(y)), 0, uSourceSize.y - 1);
  int y1 = min(y0 + 1, uSourceSize.y - 1);
  float fy = clamp(y - float(y0), 0.0, 1.0);
  float x = (float(p.x) + 0.5) * s.x - 0.5;
  int xf = int(floor(x));
  float fx = x - float(xf);
  int x0 = (xf % uSourceSize.x + uSourceSize.x) % uSourceSize.x;
  int x1 = (x0 + 1) % uSourceSize.x;
  vec3 v = (1.0 - fy) * ((1.0 - fx) * at(x0, y0) + fx * at(x1, y0)) + fy * ((1.0 - fx) * at(x0, y1) + fx * at(x1, y1));
  target[p.y * uTargetSize.x + p.x] = vec4(v, 0.0);
}
