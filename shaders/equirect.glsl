// The equirectangular convention (engine/sphere/equirect.h is the one definition; this mirrors it).
// Frame: +Y up, forward +X, right +Z. Pixel centres at +0.5; row 0 at the zenith; the centre
// column looks forward; the seam (lon = +-pi) is the image's left/right edge.
const float kPi = 3.14159265358979323846;

vec3 equirectDirection(vec2 xy, ivec2 size) {
  float lon = kPi * (1.0 - 2.0 * xy.x / float(size.x));
  float lat = 0.5 * kPi - kPi * xy.y / float(size.y);
  float c = cos(lat);
  return vec3(c * cos(lon), sin(lat), -c * sin(lon));
}

vec2 equirectPixel(vec3 d, ivec2 size) {
  d = normalize(d);
  float lat = asin(clamp(d.y, -1.0, 1.0));
  float lon = atan(-d.z, d.x);
  float x = 0.5 * (1.0 - lon / kPi) * float(size.x);
  return vec2(mod(x, float(size.x)), (0.5 * kPi - lat) / kPi * float(size.y));
}

float equirectPixelSolidAngle(int row, ivec2 size) {
  float lat_top = 0.5 * kPi - kPi * float(row) / float(size.y);
  float lat_bottom = 0.5 * kPi - kPi * float(row + 1) / float(size.y);
  return 2.0 * kPi / float(size.x) * (sin(lat_top) - sin(lat_bottom));
}
