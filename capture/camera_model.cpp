#include "capture/camera_model.h"

#include <Eigen/Dense>

#include <cmath>
#include <cstdio>
#include <limits>

#include "core/constants.h"
#include "core/error.h"
#include "engine/sphere/equirect.h"

namespace odvr::capture {
namespace {

void CheckSize(int width, int height) {
  if (width <= 0 || height <= 0)
    throw Error("camera model", "image size " + std::to_string(width) + "x" + std::to_string(height) + " is empty");
}

void CheckFocal(double fx, double fy) {
  if (!(fx > 0 && fy > 0 && std::isfinite(fx) && std::isfinite(fy)))
    throw Error("camera model", "focal lengths must be positive and finite");
}

// Kannala-Brandt polynomial theta_d(theta) and its derivative.
void FisheyeDistort(const std::vector<double>& k, double theta, double* theta_d, double* dtheta_d) {
  const double t2 = theta * theta, t4 = t2 * t2, t6 = t4 * t2, t8 = t4 * t4;
  *theta_d = theta * (1 + k[0] * t2 + k[1] * t4 + k[2] * t6 + k[3] * t8);
  *dtheta_d = 1 + 3 * k[0] * t2 + 5 * k[1] * t4 + 7 * k[2] * t6 + 9 * k[3] * t8;
}

// Radial-tangential distortion of normalized coordinates (x, y) and its 2x2 Jacobian.
void RadtanDistort(const std::vector<double>& d, double x, double y, Eigen::Vector2d* out, Eigen::Matrix2d* jac) {
  const double k1 = d[0], k2 = d[1], p1 = d[2], p2 = d[3], k3 = d[4];
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2);  // d radial / d r2
  (*out) << x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  if (jac) {
    (*jac)(0, 0) = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x;
    (*jac)(0, 1) = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y;
    (*jac)(1, 0) = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y;
    (*jac)(1, 1) = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x;
  }
}

}  // namespace

std::string ToString(CameraModelType type) {
  switch (type) {
    case CameraModelType::kPinhole:
      return "pinhole";
    case CameraModelType::kFisheye:
      return "fisheye";
    case CameraModelType::kEquirectangular:
      return "equirectangular";
  }
  return "?";
}

CameraModel CameraModel::Pinhole(int width, int height, double fx, double fy, double cx, double cy,
                                 const std::array<double, 5>& distortion) {
  return Make(CameraModelType::kPinhole, width, height, fx, fy, cx, cy, {distortion.begin(), distortion.end()});
}

CameraModel CameraModel::Fisheye(int width, int height, double fx, double fy, double cx, double cy,
                                 const std::array<double, 4>& k) {
  return Make(CameraModelType::kFisheye, width, height, fx, fy, cx, cy, {k.begin(), k.end()});
}

CameraModel CameraModel::Make(CameraModelType type, int width, int height, double fx, double fy, double cx, double cy,
                              std::vector<double> distortion) {
  CheckSize(width, height);
  CheckFocal(fx, fy);
  CameraModel m;
  m.type_ = type;
  m.width_ = width;
  m.height_ = height;
  m.fx_ = fx;
  m.fy_ = fy;
  m.cx_ = cx;
  m.cy_ = cy;
  m.distortion_ = std::move(distortion);
  m.ComputeMaxTheta();
  return m;
}

CameraModel CameraModel::Equirectangular(int width, int height) {
  CheckSize(width, height);
  CameraModel m;
  m.type_ = CameraModelType::kEquirectangular;
  m.width_ = width;
  m.height_ = height;
  m.fx_ = width / (2 * kPi);
  m.fy_ = height / kPi;
  m.cx_ = width / 2.0 - 0.5;
  m.cy_ = height / 2.0 - 0.5;
  m.max_theta_ = kPi;
  return m;
}

void CameraModel::ComputeMaxTheta() {
  // Walk outwards until the radial map stops growing: past that point two rays share a pixel,
  // so projection would no longer be invertible (and the stitcher would ghost far-off content).
  constexpr double kStep = 1e-4;
  if (type_ == CameraModelType::kFisheye) {
    max_theta_ = kPi;
    for (double t = kStep; t <= kPi; t += kStep) {
      double td, dtd;
      FisheyeDistort(distortion_, t, &td, &dtd);
      if (dtd <= 0) {
        max_theta_ = t - kStep;
        break;
      }
    }
  } else if (type_ == CameraModelType::kPinhole) {
    const double k1 = distortion_[0], k2 = distortion_[1], k3 = distortion_[4];
    max_theta_ = kPi / 2;
    max_r2_ = std::numeric_limits<double>::infinity();
    for (double t = kStep; t < kPi / 2; t += kStep) {
      const double r2 = std::tan(t) * std::tan(t);
      if (1 + r2 * (3 * k1 + r2 * (5 * k2 + r2 * 7 * k3)) <= 0) {
        max_theta_ = t - kStep;
        max_r2_ = std::tan(max_theta_) * std::tan(max_theta_);
        break;
      }
    }
  }
}

bool CameraModel::Project(const Eigen::Vector3d& p, Eigen::Vector2d* pixel,
                          Eigen::Matrix<double, 2, 3>* jacobian) const {
  const double X = p.x(), Y = p.y(), Z = p.z();
  const double r2 = X * X + Y * Y + Z * Z;
  if (!(r2 > 0) || !std::isfinite(r2)) return false;
  switch (type_) {
    case CameraModelType::kPinhole: {
      if (Z <= 1e-12 * std::sqrt(r2)) return false;
      const double x = X / Z, y = Y / Z;
      if (x * x + y * y > max_r2_) return false;
      Eigen::Vector2d d;
      Eigen::Matrix2d dd;
      RadtanDistort(distortion_, x, y, &d, jacobian ? &dd : nullptr);
      (*pixel) << fx_ * d.x() + cx_, fy_ * d.y() + cy_;
      if (jacobian) {
        Eigen::Matrix<double, 2, 3> dn;  // d (x, y) / d (X, Y, Z)
        dn << 1 / Z, 0, -X / (Z * Z), 0, 1 / Z, -Y / (Z * Z);
        Eigen::Matrix2d f = Eigen::Vector2d(fx_, fy_).asDiagonal();
        *jacobian = f * dd * dn;
      }
      return true;
    }
    case CameraModelType::kFisheye: {
      const double rho = std::hypot(X, Y);
      const double theta = std::atan2(rho, Z);
      if (theta > max_theta_) return false;
      double td, dtd;
      FisheyeDistort(distortion_, theta, &td, &dtd);
      if (rho <= 1e-12 * std::sqrt(r2)) {
        // On the axis theta_d / rho -> 1 / Z (theta ~ rho / Z): the limit, not 0/0.
        if (Z <= 0) return false;  // straight behind: every azimuth at once
        (*pixel) << cx_, cy_;
        if (jacobian) *jacobian << fx_ / Z, 0, 0, 0, fy_ / Z, 0;
        return true;
      }
      const double s = td / rho;
      (*pixel) << fx_ * s * X + cx_, fy_ * s * Y + cy_;
      if (jacobian) {
        // u = fx s X + cx with s = theta_d(theta) / rho, theta = atan2(rho, Z):
        // d theta / d(X, Y, Z) = (Z X / (rho r^2), Z Y / (rho r^2), -rho / r^2).
        const Eigen::Vector3d dtheta(Z * X / (rho * r2), Z * Y / (rho * r2), -rho / r2);
        const Eigen::Vector3d drho(X / rho, Y / rho, 0);
        const Eigen::Vector3d ds = (dtd * dtheta * rho - td * drho) / (rho * rho);
        jacobian->row(0) = fx_ * (X * ds.transpose() + Eigen::RowVector3d(s, 0, 0));
        jacobian->row(1) = fy_ * (Y * ds.transpose() + Eigen::RowVector3d(0, s, 0));
      }
      return true;
    }
    case CameraModelType::kEquirectangular: {
      // Camera frame -> odvr frame (forward +X, up +Y, right +Z) = (Z, -Y, X); the equirect
      // convention itself is engine/sphere/equirect.h, whose pixel centres sit at +0.5.
      const glm::dvec2 e = sphere::EquirectPixel(glm::dvec3(Z, -Y, X), width_, height_);
      (*pixel) << e.x - 0.5, e.y - 0.5;
      if (jacobian) {
        // lon = atan2(-X, Z), col = W (1/2 - lon / 2pi); lat = atan2(-Y, hypot(X, Z)), row = H (1/2 - lat / pi).
        const double h2 = X * X + Z * Z, h = std::sqrt(h2);
        if (h <= 1e-12 * std::sqrt(r2)) return false;  // the poles: longitude has no derivative
        const Eigen::RowVector3d dlon(-Z / h2, 0, X / h2);
        const Eigen::RowVector3d dlat(Y * X / (h * r2), -h / r2, Y * Z / (h * r2));
        jacobian->row(0) = -width_ / (2 * kPi) * dlon;
        jacobian->row(1) = -height_ / kPi * dlat;
      }
      return true;
    }
  }
  return false;
}

bool CameraModel::Unproject(const Eigen::Vector2d& pixel, Eigen::Vector3d* bearing) const {
  if (!pixel.allFinite()) return false;
  switch (type_) {
    case CameraModelType::kPinhole: {
      const Eigen::Vector2d target((pixel.x() - cx_) / fx_, (pixel.y() - cy_) / fy_);
      // Newton on the 2D distortion map, from the undistorted guess; it converges in a few
      // steps inside the monotonic region and is rejected outside it.
      Eigen::Vector2d x = target;
      for (int it = 0; it < 50; ++it) {
        Eigen::Vector2d d;
        Eigen::Matrix2d j;
        RadtanDistort(distortion_, x.x(), x.y(), &d, &j);
        const Eigen::Vector2d r = d - target;
        if (r.norm() < 1e-14) break;
        const double det = j.determinant();
        if (std::abs(det) < 1e-12) return false;
        x -= j.inverse() * r;
        if (!x.allFinite()) return false;
      }
      if (x.squaredNorm() > max_r2_) return false;
      Eigen::Vector2d d;
      RadtanDistort(distortion_, x.x(), x.y(), &d, nullptr);
      if ((d - target).norm() * std::max(fx_, fy_) > 1e-6) return false;
      *bearing = Eigen::Vector3d(x.x(), x.y(), 1).normalized();
      return true;
    }
    case CameraModelType::kFisheye: {
      const double mx = (pixel.x() - cx_) / fx_, my = (pixel.y() - cy_) / fy_;
      const double target = std::hypot(mx, my);
      if (target < 1e-15) {
        *bearing = Eigen::Vector3d(0, 0, 1);
        return true;
      }
      double td_max, unused;
      FisheyeDistort(distortion_, max_theta_, &td_max, &unused);
      if (target > td_max) return false;
      // theta_d is increasing on [0, max_theta]: safeguarded Newton (bisection when a step leaves
      // the bracket) always converges.
      double lo = 0, hi = max_theta_, theta = std::min(target, max_theta_);
      for (int it = 0; it < 100; ++it) {
        double td, dtd;
        FisheyeDistort(distortion_, theta, &td, &dtd);
        const double f = td - target;
        if (std::abs(f) < 1e-15) break;
        (f > 0 ? hi : lo) = theta;
        double next = dtd > 0 ? theta - f / dtd : 0.5 * (lo + hi);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (std::abs(next - theta) < 1e-16) break;
        theta = next;
      }
      const double s = std::sin(theta) / target;
      *bearing = Eigen::Vector3d(s * mx, s * my, std::cos(theta));
      return true;
    }
    case CameraModelType::kEquirectangular: {
      if (pixel.y() < -0.5 || pixel.y() > height_ - 0.5) return false;
      const glm::dvec3 d = sphere::EquirectDirection(pixel.x() + 0.5, pixel.y() + 0.5, width_, height_);
      *bearing = Eigen::Vector3d(d.z, -d.y, d.x).normalized();
      return true;
    }
  }
  return false;
}

std::string CameraModel::Describe() const {
  char buf[256];
  std::string d;
  for (std::size_t i = 0; i < distortion_.size(); ++i) {
    char v[32];
    std::snprintf(v, sizeof v, "%s%g", i ? ", " : "", distortion_[i]);
    d += v;
  }
  if (type_ == CameraModelType::kEquirectangular) {
    std::snprintf(buf, sizeof buf, "equirectangular %dx%d", width_, height_);
  } else {
    std::snprintf(buf, sizeof buf, "%s %dx%d f=(%.6g, %.6g) c=(%.6g, %.6g) k=[%s]", ToString(type_).c_str(), width_,
                  height_, fx_, fy_, cx_, cy_, d.c_str());
  }
  return buf;
}

}  // namespace odvr::capture
