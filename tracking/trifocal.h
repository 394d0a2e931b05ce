#pragma once
// The trifocal tensor of three views (Hartley & Zisserman, "Multiple View Geometry", 2nd ed.,
// ch. 15-16): estimated from point triples by the normalized linear algorithm with the
// algebraic-minimization step that makes it geometrically valid (Alg. 16.1 + 16.2's core), point
// transfer, and the estimator that plugs it into the generic RANSAC (tracking/ransac.h) to reject
// tracks that do not transfer across three consecutive frames (seed §5.3.2).
//
// Points are normalized image coordinates: a bearing b of a camera divided by b.z (the z = 1
// plane), so a fisheye's pixels go through capture/camera_model.h first. Bearings at or behind
// 90 degrees have no such point; a caller drops them (or rotates the view first).
//
// Convention (H&Z 15.1): slice i is the 3x3 matrix T[i](j, k) = T_i^{jk}. For the cameras
// P1 = [I | 0], P2 = [A | a4], P3 = [B | b4], T_i = a_i b4^T - a4 b_i^T, with a_i, b_i the i-th
// columns of A and B.
#include <Eigen/Core>
#include <array>
#include <vector>

#include "tracking/ransac.h"

namespace odvr::tracking {

// One point seen in views 1, 2 and 3, in normalized image coordinates.
struct PointTriple {
  Eigen::Vector2d x1, x2, x3;
};

class TrifocalTensor {
 public:
  TrifocalTensor() = default;
  // Takes the slices; epipoles and the fundamental matrices F21, F31 that transfer needs are
  // derived once here.
  explicit TrifocalTensor(const std::array<Eigen::Matrix3d, 3>& slices);

  // The tensor of calibrated cameras given by their poses relative to the first one
  // (x_cam2 = R21 x_cam1 + t21, likewise for the third view).
  static TrifocalTensor FromRelativePoses(const Eigen::Matrix3d& R21, const Eigen::Vector3d& t21,
                                          const Eigen::Matrix3d& R31, const Eigen::Vector3d& t31);

  const std::array<Eigen::Matrix3d, 3>& slices() const { return slices_; }
  // The 27 entries, index 9 i + 3 j + k, scaled to unit norm with the largest |entry| positive:
  // two tensors equal up to scale have equal Normalized().
  Eigen::Matrix<double, 27, 1> Normalized() const;

  // Epipoles in views 2 and 3 (images of camera 1's centre), unit norm.
  const Eigen::Vector3d& epipole2() const { return e2_; }
  const Eigen::Vector3d& epipole3() const { return e3_; }
  // x2^T F21 x1 = 0, x3^T F31 x1 = 0 (H&Z 15.9).
  const Eigen::Matrix3d& F21() const { return F21_; }
  const Eigen::Matrix3d& F31() const { return F31_; }

  // x3 predicted from (x1, x2) through the line in view 2 that passes through x2 perpendicular to
  // x1's epipolar line (H&Z 15.2.2: the perpendicular line avoids the degenerate choice, the
  // epipolar line itself). False when the prediction is at infinity.
  bool TransferToThird(const Eigen::Vector2d& x1, const Eigen::Vector2d& x2, Eigen::Vector2d* x3) const;
  // x2 predicted from (x1, x3), the same construction with the roles of views 2 and 3 swapped.
  bool TransferToSecond(const Eigen::Vector2d& x1, const Eigen::Vector2d& x3, Eigen::Vector2d* x2) const;

  // The larger of the two transfer errors |x3 - x3(x1, x2)| and |x2 - x2(x1, x3)| in normalized
  // coordinates (multiply by the focal length for pixels). Both directions are needed: moving x2
  // along the transfer line of view 2 leaves x3's prediction unchanged, and vice versa. +inf when
  // a prediction is at infinity.
  double TransferError(const PointTriple& p) const;

  // The geometric residual RANSAC uses: the point triangulated (DLT) from all three views with the
  // cameras the tensor implies (H&Z 15.1.4: P1 = [I | 0], P2 = [[T1 T2 T3] e3 | e2],
  // P3 = [(e3 e3^T - I) [T1^T T2^T T3^T] e2 | e3]), reprojected; the largest of the three
  // distances, in normalized coordinates. Unlike transfer it stays well conditioned for points
  // near the epipoles, which forward motion puts in the middle of the image. +inf when the
  // point reprojects to infinity.
  double ReprojectionError(const PointTriple& p) const;

  // The projective cameras above (3x4); camera 1 is [I | 0].
  const Eigen::Matrix<double, 3, 4>& P2() const { return P2_; }
  const Eigen::Matrix<double, 3, 4>& P3() const { return P3_; }

 private:
  std::array<Eigen::Matrix3d, 3> slices_{Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Zero()};
  Eigen::Vector3d e2_ = Eigen::Vector3d::Zero(), e3_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d F21_ = Eigen::Matrix3d::Zero(), F31_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix<double, 3, 4> P2_ = Eigen::Matrix<double, 3, 4>::Zero(), P3_ = Eigen::Matrix<double, 3, 4>::Zero();
};

// The normalized linear algorithm (H&Z Alg. 16.1) on >= 7 triples: Hartley normalization per view,
// the 4 independent point-point-point incidence equations [x2]x (sum_i x1^i T_i) [x3]x = 0 per
// triple, the SVD null vector, then the algebraic minimization that re-fits T = a_i e3^T - e2 b_i^T
// with the epipoles of the linear solution (so that the result is a valid tensor and transfer is
// consistent), and denormalization. False for degenerate input (coincident points, a rank
// deficiency that leaves no unique solution). Throws odvr::Error for fewer than 7 triples.
bool EstimateTrifocalLinear(const std::vector<PointTriple>& triples, TrifocalTensor* tensor);

// The RANSAC estimator: a minimal-size sample of 7 for the linear solver, the same solver as the
// least-squares refit on all inliers, ReprojectionError as the residual.
struct TrifocalEstimator {
  using Datum = PointTriple;
  using Model = TrifocalTensor;
  static constexpr int kMinimalSample = 7;

  std::vector<Model> Estimate(const std::vector<Datum>& data) const;
  void Residuals(const std::vector<Datum>& data, const Model& model, std::vector<double>* residuals) const;
};

}  // namespace odvr::tracking
