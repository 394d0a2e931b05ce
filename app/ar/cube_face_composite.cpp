#include "app/ar/cube_face_composite.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <opencv2/core/utility.hpp>

#include "core/constants.h"
#include "engine/sphere/equirect.h"

namespace odvr::app {
namespace {

// Where a face's layers show something another face must carry on: the car's coverage, or a
// shadow darker than one 8-bit step of the brightest value shows (1/255 ≈ 0.4 %).
constexpr float kCoverageSeen = 1e-3f, kShadowSeen = 2e-3f;

// Bilinear sample of `channels` interleaved floats at continuous pixel coordinates (x, y), pixel
// centres at +0.5, clamped at the image's edge.
void Sample(const std::vector<float>& image, int width, int height, int channels, double x, double y, float* out) {
  const double u = std::clamp(x - 0.5, 0.0, width - 1.0), v = std::clamp(y - 0.5, 0.0, height - 1.0);
  const int x0 = std::min(static_cast<int>(u), std::max(width - 2, 0));
  const int y0 = std::min(static_cast<int>(v), std::max(height - 2, 0));
  const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
  const auto fx = static_cast<float>(u - x0), fy = static_cast<float>(v - y0);
  const auto at = [&](int xx, int yy, int c) {
    return image[(static_cast<std::size_t>(yy) * width + xx) * channels + static_cast<std::size_t>(c)];
  };
  for (int c = 0; c < channels; ++c) {
    const float top = at(x0, y0, c) + fx * (at(x1, y0, c) - at(x0, y0, c));
    const float bottom = at(x0, y1, c) + fx * (at(x1, y1, c) - at(x0, y1, c));
    out[c] = top + fy * (bottom - top);
  }
}

// The up hint of a face's camera (panorama frame): the zenith for the four around the horizon, the
// forward for the two at the poles.
glm::dvec3 CubeFaceUp(int face) { return face == 2 || face == 3 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0); }

}  // namespace

int CubeFaceOf(const glm::dvec3& d) {
  const glm::dvec3 a = glm::abs(d);
  if (a.x >= a.y && a.x >= a.z) return d.x >= 0 ? 0 : 1;
  if (a.y >= a.z) return d.y >= 0 ? 2 : 3;
  return d.z >= 0 ? 4 : 5;
}

glm::dvec3 CubeFaceAxis(int face) {
  glm::dvec3 axis(0);
  axis[face / 2] = face % 2 ? -1 : 1;
  return axis;
}

render::PinholeCamera CubeFaceCamera(int face, int side, const glm::dvec3& eye, const glm::dmat3& car_from_pano) {
  // The face proper, side − 2m pixels, spans tan 45° = 1 each side of the axis: focal = (side − 2m)/2.
  const double inner = side - 2.0 * kCubeFaceMargin;
  const double vfov_deg = 2 * std::atan(side / inner) * 180 / kPi;
  return render::PinholeCamera::LookAt(eye, eye + car_from_pano * CubeFaceAxis(face), vfov_deg, side, side,
                                       car_from_pano * CubeFaceUp(face));
}

CubeFaceLayers TakeCubeFaceLayers(const render::PinholeCamera& camera, const render::RenderResult& layers) {
  CubeFaceLayers f;
  f.camera = camera;
  f.alpha = layers.car_alpha;
  f.shadow = layers.shadow.rgb;
  f.car_premultiplied = layers.car.rgb;
  for (std::size_t p = 0; p < f.alpha.size(); ++p)
    for (int c = 0; c < 3; ++c) f.car_premultiplied[3 * p + static_cast<std::size_t>(c)] *= f.alpha[p];
  return f;
}

std::vector<int> CubeFacesMeetingSphere(const glm::dvec3& centre, double radius) {
  const double distance = glm::length(centre);
  if (distance <= radius) return {0, 1, 2, 3, 4, 5};
  // A face's frustum lies within the cone around its axis through its corners: acos(1/√3).
  const double corner = std::acos(1 / std::sqrt(3.0)), disc = std::asin(radius / distance);
  std::vector<int> faces;
  for (int face = 0; face < 6; ++face) {
    const double angle = std::acos(std::clamp(glm::dot(CubeFaceAxis(face), centre / distance), -1.0, 1.0));
    if (angle <= corner + disc) faces.push_back(face);
  }
  return faces;
}

std::vector<int> CubeFacesBeyondBorder(int face, const CubeFaceLayers& layers, const glm::dmat3& pano_from_car) {
  const render::PinholeCamera& camera = layers.camera;
  const int w = camera.width, h = camera.height;
  std::vector<int> beyond;
  const auto check = [&](int x, int y) {
    const std::size_t p = static_cast<std::size_t>(y) * w + x;
    const bool seen = layers.alpha[p] > kCoverageSeen || std::min({layers.shadow[3 * p], layers.shadow[3 * p + 1],
                                                                   layers.shadow[3 * p + 2]}) < 1 - kShadowSeen;
    if (!seen) return;
    // The outermost ring lies past the face's 90°: its rays fall on the neighbouring faces.
    const int other = CubeFaceOf(pano_from_car * camera.Ray(x + 0.5, y + 0.5));
    if (other != face && std::find(beyond.begin(), beyond.end(), other) == beyond.end()) beyond.push_back(other);
  };
  for (int x = 0; x < w; ++x) check(x, 0), check(x, h - 1);
  for (int y = 1; y + 1 < h; ++y) check(0, y), check(w - 1, y);
  return beyond;
}

int CompositeCubeFaces(const CubeFaces& faces, const glm::dmat3& car_from_pano, sphere::EquirectImage* pano) {
  const int width = pano->width, height = pano->height;
  // Each face's rotation from the panorama's frame into its camera's: c = camera_from_pano · d.
  std::array<glm::dmat3, 6> camera_from_pano;
  for (int f = 0; f < 6; ++f)
    if (faces[static_cast<std::size_t>(f)])
      camera_from_pano[static_cast<std::size_t>(f)] =
          glm::transpose(faces[static_cast<std::size_t>(f)]->camera.world_from_camera) * car_from_pano;
  std::vector<int> covered(static_cast<std::size_t>(height), 0);
  cv::parallel_for_(cv::Range(0, height), [&](const cv::Range& rows) {
    for (int row = rows.start; row < rows.end; ++row) {
      for (int col = 0; col < width; ++col) {
        const glm::dvec3 d = sphere::EquirectPixelDirection(col, row, width, height);
        const int f = CubeFaceOf(d);
        const auto& face = faces[static_cast<std::size_t>(f)];
        if (!face) continue;
        const glm::dvec3 c = camera_from_pano[static_cast<std::size_t>(f)] * d;
        const render::PinholeCamera& cam = face->camera;
        const double focal = cam.focal_px();
        const double x = focal * c.x / c.z + 0.5 * cam.width, y = focal * c.y / c.z + 0.5 * cam.height;
        float car[3], alpha, shadow[3];
        Sample(face->car_premultiplied, cam.width, cam.height, 3, x, y, car);
        Sample(face->alpha, cam.width, cam.height, 1, x, y, &alpha);
        Sample(face->shadow, cam.width, cam.height, 3, x, y, shadow);
        alpha = std::clamp(alpha, 0.f, 1.f);
        float* p = pano->at(col, row);
        for (int k = 0; k < 3; ++k) p[k] = p[k] * shadow[k] * (1 - alpha) + car[k];
        covered[static_cast<std::size_t>(row)] += alpha >= 0.5f;
      }
    }
  });
  int total = 0;
  for (const int n : covered) total += n;
  return total;
}

}  // namespace odvr::app
