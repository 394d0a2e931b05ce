#pragma once
// THE equirectangular convention of odvr (DESIGN.md §3). Everything that maps pixels to
// directions goes through here (CPU) or shaders/equirect.glsl (GPU); tests hold both to it.
//
// Frame: right-handed, +Y up, forward = +X, right = +Z (the Y-up form of the rig frame
// "x forward, y left, z up" used by ../shared/data/street_*, via (x, y, z) -> (x, z, -y)).
// Pixel (col, row) of a W x H image, pixel centres at +0.5:
//   longitude lon = pi * (1 - 2 (col + 0.5) / W)   counter-clockwise from +X seen from above,
//                                                  so the centre column looks forward (+X), the
//                                                  column index grows towards the right (+Z), and
//                                                  the seam (lon = +-pi) is the left/right edge,
//                                                  looking backward (-X);
//   latitude  lat = pi/2 - pi (row + 0.5) / H      row 0 touches the zenith (+Y), the last row the nadir;
//   direction = (cos lat cos lon, sin lat, -cos lat sin lon).
// The solid angle of a pixel is exact: (2 pi / W) (sin lat_top - sin lat_bottom); it sums to 4 pi.
#include <glm/mat3x3.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "core/axes.h"
#include "core/constants.h"

namespace odvr::sphere {

// The Z-up world of the datasets and Blender in this frame (core/axes.h), for glm.
inline glm::dmat3 YupFromZup() {
  glm::dmat3 c;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) c[k][r] = kYupFromZup[r][k];  // glm is column-major
  return c;
}

// Direction of continuous image coordinates (x, y) in pixels, where pixel centres sit at +0.5.
glm::dvec3 EquirectDirection(double x, double y, int width, int height);

// Direction through the centre of pixel (col, row).
inline glm::dvec3 EquirectPixelDirection(int col, int row, int width, int height) {
  return EquirectDirection(col + 0.5, row + 0.5, width, height);
}

// Continuous pixel coordinates (x in [0, W), y in [0, H]) of a direction (need not be unit).
glm::dvec2 EquirectPixel(const glm::dvec3& direction, int width, int height);

// Solid angle of any pixel in row `row` (steradians).
double EquirectPixelSolidAngle(int row, int width, int height);

// The pixels of a width x height grid that can lie in the cap {d : d·axis > cos_max} (axis
// unit): rows first_row..last_row and, in each, `count` columns from `start` (wrapping: start
// may be negative; count 0 where the row misses the cap, the whole row near a pole). A superset
// by a column or more each side: callers test each pixel.
class EquirectCap {
 public:
  EquirectCap(const glm::dvec3& axis, double cos_max, int width, int height);
  int first_row() const { return first_row_; }
  int last_row() const { return last_row_; }
  struct Span {
    int start = 0, count = 0;
  };
  Span Columns(int row) const;

 private:
  int width_, height_, first_row_, last_row_;
  double sin_lat_c_, cos_lat_c_, cos_theta_, col_c_;
};

}  // namespace odvr::sphere
