#pragma once
// The augmented 360° frame (AugmentedScene::RenderEquirect): the renderer draws through a pinhole,
// so the car and its shadow are rendered through the faces of a cube around the viewer and each
// face's layers are resampled into the panorama, over the recorded pixels. Only the faces that
// show the car or its shadow are rendered: those its bounding sphere reaches, then each face beyond
// an edge the car or its shadow crosses, so that a long shadow is followed onto the next face.
//
// Faces live in the panorama's frame (engine/sphere/equirect.h: +Y up, forward +X, right +Z):
// 0 +X, 1 −X, 2 +Y, 3 −Y, 4 +Z, 5 −Z. A face's camera looks along its axis with a field of view a
// little over 90° (kCubeFaceMargin pixels each side), so that bilinear sampling at a face's edge
// reads rendered pixels on both sides.
#include <array>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>
#include <optional>
#include <vector>

#include "engine/render/triple_product_renderer.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::app {

inline constexpr int kCubeFaceMargin = 2;

// A face's layers, as RenderResult holds them (rows top first, size of the camera).
struct CubeFaceLayers {
  render::PinholeCamera camera;          // in the renderer's (car's) frame
  std::vector<float> car_premultiplied;  // RGB × coverage
  std::vector<float> alpha;              // coverage
  std::vector<float> shadow;             // RGB ratio, 1 where the car shadows nothing
};
using CubeFaces = std::array<std::optional<CubeFaceLayers>, 6>;

int CubeFaceOf(const glm::dvec3& pano_direction);
glm::dvec3 CubeFaceAxis(int face);
// The face's camera: at `eye` (car frame) looking along the face's axis, `side` pixels square
// (kCubeFaceMargin of them beyond the face's 90° on each side).
render::PinholeCamera CubeFaceCamera(int face, int side, const glm::dvec3& eye, const glm::dmat3& car_from_pano);
CubeFaceLayers TakeCubeFaceLayers(const render::PinholeCamera& camera, const render::RenderResult& layers);

// Faces that can show a sphere (centre relative to the viewer, panorama frame): those whose
// circumscribed cone, 54.7° around the axis, meets the sphere's angular disc. All six when the
// viewer is inside it.
std::vector<int> CubeFacesMeetingSphere(const glm::dvec3& centre, double radius);
// The faces beyond the edges of `face` where its car covers or its shadow darkens a border pixel.
std::vector<int> CubeFacesBeyondBorder(int face, const CubeFaceLayers& layers, const glm::dmat3& pano_from_car);

// Composites the rendered faces over `pano` (linear RGB, the panorama's frame): each pixel whose
// direction falls on a rendered face becomes pano × shadow × (1 − α) + car × α, sampled
// bilinearly from that face; the others keep their recorded value. Returns the pixels the car
// covers at least half.
int CompositeCubeFaces(const CubeFaces& faces, const glm::dmat3& car_from_pano, sphere::EquirectImage* pano);

}  // namespace odvr::app
