#pragma once
// The HEALPix hierarchy the lighting lives on (seed §4.4.1.1, DESIGN.md §4), from Debian's
// healpix_cxx in NESTED ordering: level s has 12·4^s centres and the four children of centre i
// at level s are 4i..4i+3 at level s+1.
//
// Frame: HEALPix's own pole (+z) is odvr's up (+Y); its (x, y, z) maps to odvr's (x, z, −y),
// the same map that takes the rig frame (x forward, y left, z up) to odvr's Y-up frame, so
// HEALPix φ = 0 looks forward (+X). See engine/sphere/equirect.h for the frame itself.
#include <array>
#include <glm/vec3.hpp>
#include <vector>

namespace odvr::sphere {

constexpr int kMaxHealpixLevel = 8;

// 12 · 4^level.
inline int HealpixCount(int level) { return 12 << (2 * level); }

class HealpixLevel {
 public:
  explicit HealpixLevel(int level);  // 0 ≤ level ≤ kMaxHealpixLevel; throws odvr::Error otherwise

  int level() const { return level_; }
  int size() const { return static_cast<int>(centres_.size()); }
  const std::vector<glm::dvec3>& centres() const { return centres_; }
  const glm::dvec3& centre(int i) const { return centres_[static_cast<std::size_t>(i)]; }

  // The nested index of the HEALPix cell containing direction d (need not be unit).
  int CellOf(const glm::dvec3& d) const;
  // Up to 8 neighbouring cells (−1 where a cell has only 7).
  std::array<int, 8> Neighbours(int i) const;
  // The largest angle from a centre to a corner of its cell (radians).
  double MaxCellRadius() const { return max_cell_radius_; }

  // α: the mean, over the level's centres, of the angle to the nearest neighbouring centre.
  double MeanNeighbourAngle() const { return mean_neighbour_angle_; }
  // Lobe sharpness of the level's SGs: λ = ln(1/2) / (cos(α/2) − 1), so that two neighbouring
  // Gaussians each fall to 1/2 halfway between their centres. Levels 0–4 give the seed's
  // 5.50, 22.55, 91.50, 364.51, 1449.29.
  double Lambda() const { return lambda_; }

 private:
  int level_;
  std::vector<glm::dvec3> centres_;
  double mean_neighbour_angle_ = 0;
  double lambda_ = 0;
  double max_cell_radius_ = 0;
};

// Levels are immutable and costly enough to build (neighbour search) to share: cached per level.
const HealpixLevel& Healpix(int level);

// Conversions between HEALPix's frame and odvr's.
inline glm::dvec3 FromHealpixFrame(double x, double y, double z) { return {x, z, -y}; }
inline glm::dvec3 ToHealpixFrame(const glm::dvec3& d) { return {d.x, -d.z, d.y}; }

}  // namespace odvr::sphere
