#pragma once
// Camera models around unit bearing vectors (STYLE.md, after COLMAP and stella_vslam): every
// model maps a point in the OpenCV camera frame (x right, y down, z forward) to a pixel and a
// pixel back to a unit bearing, so the stitcher and the tracker need no special cases for a
// fisheye, a pinhole or a whole 360° frame.
//
// Pixels follow OpenCV: pixel centres at integer coordinates, (0, 0) is the centre of the
// top-left pixel, so an image spans [-0.5, W - 0.5] x [-0.5, H - 0.5]. The equirectangular
// model converts to and from engine/sphere/equirect.h (centres at +0.5) and is defined by it.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

namespace odvr::capture {

enum class CameraModelType {
  kPinhole,          // pinhole + radial-tangential (OpenCV's k1, k2, p1, p2, k3)
  kFisheye,          // Kannala-Brandt / OpenCV fisheye: theta_d = theta (1 + k1 t^2 + k2 t^4 + k3 t^6 + k4 t^8)
  kEquirectangular,  // a whole sphere; the image is an odvr equirect frame seen from the camera
};

std::string ToString(CameraModelType type);

class CameraModel {
 public:
  // Distortion order as OpenCV's cv::projectPoints takes it: k1, k2, p1, p2, k3.
  static CameraModel Pinhole(int width, int height, double fx, double fy, double cx, double cy,
                             const std::array<double, 5>& distortion = {});
  static CameraModel Fisheye(int width, int height, double fx, double fy, double cx, double cy,
                             const std::array<double, 4>& k = {});
  // Camera frame -> equirect: forward (+z) is the centre column, right (+x) grows the column,
  // up (-y) is row 0, i.e. odvr's Y-up frame (forward +X, up +Y, right +Z) = (z, -y, x).
  static CameraModel Equirectangular(int width, int height);

  CameraModelType type() const { return type_; }
  int width() const { return width_; }
  int height() const { return height_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  // Pinhole: k1, k2, p1, p2, k3; fisheye: k1..k4; equirectangular: none.
  const std::vector<double>& distortion() const { return distortion_; }
  // Largest angle from the optical axis the model projects one-to-one (radians): pi for an
  // equirect, where theta_d(theta) stops growing for a fisheye, where the radial-tangential
  // polynomial folds back for a pinhole (beyond it a far-off ray would land inside the image).
  double max_theta() const { return max_theta_; }

  // Pixel of the camera-frame point `p` (any length > 0). False when the model cannot see it
  // (behind a pinhole, beyond max_theta); `pixel` and `jacobian` are then left unspecified.
  // `jacobian` (optional) is d pixel / d p.
  bool Project(const Eigen::Vector3d& p, Eigen::Vector2d* pixel, Eigen::Matrix<double, 2, 3>* jacobian = nullptr) const;

  // Unit bearing of `pixel`. False when no ray of the model lands there (e.g. beyond the
  // fisheye's max_theta or outside an equirect's rows).
  bool Unproject(const Eigen::Vector2d& pixel, Eigen::Vector3d* bearing) const;

  // Whether a pixel coordinate lies on the image (its pixel area, not only the centres).
  bool InImage(const Eigen::Vector2d& pixel) const {
    return pixel.x() >= -0.5 && pixel.y() >= -0.5 && pixel.x() <= width_ - 0.5 && pixel.y() <= height_ - 0.5;
  }

  // One line: "fisheye 480x640 f=(229.18, 229.18) c=(239.5, 319.5) k=[0, 0, 0, 0]".
  std::string Describe() const;

 private:
  CameraModel() = default;
  static CameraModel Make(CameraModelType type, int width, int height, double fx, double fy, double cx, double cy,
                          std::vector<double> distortion);
  void ComputeMaxTheta();
  CameraModelType type_ = CameraModelType::kPinhole;
  int width_ = 0, height_ = 0;
  double fx_ = 1, fy_ = 1, cx_ = 0, cy_ = 0;
  std::vector<double> distortion_;
  double max_theta_ = 0;
  double max_r2_ = 0;  // pinhole: largest normalized r^2 where the radial map still grows
};

}  // namespace odvr::capture
