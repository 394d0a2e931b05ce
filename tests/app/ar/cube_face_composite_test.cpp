#include "app/ar/cube_face_composite.h"

#include <gtest/gtest.h>

#include <cmath>

#include "engine/sphere/equirect.h"

namespace odvr::app {
namespace {

// A face whose layers are uniform: the car's colour at `alpha`, and a shadow ratio.
CubeFaceLayers UniformFace(int face, int side, float alpha, float red, float shadow) {
  CubeFaceLayers f;
  f.camera = CubeFaceCamera(face, side, glm::dvec3(0, 1.6, 0), glm::dmat3(1.0));
  const std::size_t n = static_cast<std::size_t>(side) * side;
  f.alpha.assign(n, alpha);
  f.shadow.assign(3 * n, shadow);
  f.car_premultiplied.assign(3 * n, 0.f);
  for (std::size_t p = 0; p < n; ++p) f.car_premultiplied[3 * p] = red * alpha;
  return f;
}

TEST(CubeFaceComposite, EachDirectionFallsOnTheFaceOfItsLargestAxis) {
  for (int face = 0; face < 6; ++face) EXPECT_EQ(CubeFaceOf(CubeFaceAxis(face)), face);
  EXPECT_EQ(CubeFaceOf({0.9, -0.5, 0.3}), 0);
  EXPECT_EQ(CubeFaceOf({0.2, -0.9, 0.3}), 3);
  EXPECT_EQ(CubeFaceOf({0.2, 0.1, -0.5}), 5);
  // A face's camera looks along its axis, and its image's edges sit kCubeFaceMargin pixels past 45°.
  const render::PinholeCamera c = CubeFaceCamera(2, 64 + 2 * kCubeFaceMargin, glm::dvec3(0), glm::dmat3(1.0));
  const glm::dvec3 centre = c.Ray(0.5 * c.width, 0.5 * c.height);
  EXPECT_NEAR(centre.y, 1.0, 1e-12);
  const glm::dvec3 edge = c.Ray(kCubeFaceMargin, 0.5 * c.height);  // the face proper's left edge
  EXPECT_NEAR(std::abs(edge.y), std::sqrt(0.5), 1e-9);
}

TEST(CubeFaceComposite, FacesMeetingASphereAreThoseItsDiscReaches) {
  // Small and far ahead: only the face ahead.
  EXPECT_EQ(CubeFacesMeetingSphere({20, 0, 0}, 1), std::vector<int>{0});
  // Ahead and below at 45°, a little larger than a point: the two faces it straddles.
  EXPECT_EQ(CubeFacesMeetingSphere({5, -5, 0}, 0.5), (std::vector<int>{0, 3}));
  // The viewer inside it: every face.
  EXPECT_EQ(CubeFacesMeetingSphere({1, 0, 0}, 2).size(), 6u);
}

TEST(CubeFaceComposite, ARenderedFaceChangesItsDirectionsAndNoOther) {
  sphere::EquirectImage pano(256, 128, 0.5f);
  CubeFaces faces;
  faces[0] = UniformFace(0, 36, 1.f, 0.8f, 1.f);   // the car over the whole face ahead
  faces[3] = UniformFace(3, 36, 0.f, 0.f, 0.25f);  // a shadow over the whole face below
  const int covered = CompositeCubeFaces(faces, glm::dmat3(1.0), &pano);
  int ahead = 0;
  for (int row = 0; row < pano.height; ++row)
    for (int col = 0; col < pano.width; ++col) {
      const glm::dvec3 d = sphere::EquirectPixelDirection(col, row, pano.width, pano.height);
      const float* p = pano.at(col, row);
      switch (CubeFaceOf(d)) {
        case 0:
          ++ahead;
          EXPECT_NEAR(p[0], 0.8f, 1e-6f);
          EXPECT_NEAR(p[1], 0.f, 1e-6f);
          break;
        case 3:
          EXPECT_NEAR(p[1], 0.125f, 1e-6f);
          break;
        default:
          EXPECT_EQ(p[1], 0.5f);  // the recorded value, exactly
      }
    }
  EXPECT_EQ(covered, ahead);
}

TEST(CubeFaceComposite, AShadowAtAFacesEdgeCallsForTheFaceBeyond) {
  CubeFaceLayers f = UniformFace(0, 20, 0.f, 0.f, 1.f);
  EXPECT_TRUE(CubeFacesBeyondBorder(0, f, glm::dmat3(1.0)).empty());
  // Darkened along the bottom row: the face below (−Y) is next.
  for (int x = 0; x < 20; ++x) f.shadow[3 * (19 * 20 + static_cast<std::size_t>(x)) + 1] = 0.9f;
  EXPECT_EQ(CubeFacesBeyondBorder(0, f, glm::dmat3(1.0)), std::vector<int>{3});
}

}  // namespace
}  // namespace odvr::app
