#include "tracking/trifocal.h"

#include <Eigen/Dense>
#include <Eigen/SVD>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.h"

namespace odvr::tracking {
namespace {

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// The unit vector n minimizing |M n| (the null vector when M is singular).
Eigen::Vector3d NullVector(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullV);
  return svd.matrixV().col(2);
}

// Hartley normalization of one view: centroid to the origin, mean distance sqrt(2). Without it
// the 27 columns of the linear system differ by powers of the coordinates' magnitude and the SVD
// null vector is dominated by that scaling rather than by the data (H&Z 4.4.4). False when all
// points coincide.
bool Normalization(const std::vector<Eigen::Vector2d>& points, Eigen::Matrix3d* h) {
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  double mean_distance = 0;
  for (const auto& p : points) mean_distance += (p - centroid).norm();
  mean_distance /= static_cast<double>(points.size());
  if (!(mean_distance > 1e-12) || !std::isfinite(mean_distance)) return false;
  const double s = std::sqrt(2.0) / mean_distance;
  *h << s, 0, -s * centroid.x(), 0, s, -s * centroid.y(), 0, 0, 1;
  return true;
}

using Vector27d = Eigen::Matrix<double, 27, 1>;

std::array<Eigen::Matrix3d, 3> SlicesOf(const Eigen::VectorXd& t) {
  std::array<Eigen::Matrix3d, 3> slices;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) slices[i](j, k) = t(9 * i + 3 * j + k);
  return slices;
}

// The point on the line through `x` perpendicular to `epipolar_line` (a homogeneous line). When
// x sits on the epipole, the epipolar line is undefined and any line through x will do.
Eigen::Vector3d PerpendicularLineThrough(const Eigen::Vector3d& epipolar_line, const Eigen::Vector2d& x) {
  Eigen::Vector2d n = epipolar_line.head<2>();
  if (n.norm() < 1e-12 * std::max(1.0, std::abs(epipolar_line.z()))) n = Eigen::Vector2d(0, 1);
  // The perpendicular line's normal is the epipolar line's direction (n.y, -n.x).
  return Eigen::Vector3d(n.y(), -n.x(), -(n.y() * x.x() - n.x() * x.y()));
}

bool Dehomogenize(const Eigen::Vector3d& h, Eigen::Vector2d* x) {
  if (!(std::abs(h.z()) > 1e-12 * h.head<2>().norm()) || !h.allFinite()) return false;
  *x = h.head<2>() / h.z();
  return true;
}

}  // namespace

TrifocalTensor::TrifocalTensor(const std::array<Eigen::Matrix3d, 3>& slices) : slices_(slices) {
  // H&Z Alg. 15.1: e2 is orthogonal to the left null vectors of all T_i, e3 to the right ones.
  Eigen::Matrix3d left_nulls, right_nulls;
  for (int i = 0; i < 3; ++i) {
    left_nulls.row(i) = NullVector(slices_[i].transpose()).transpose();
    right_nulls.row(i) = NullVector(slices_[i]).transpose();
  }
  e2_ = NullVector(left_nulls);
  e3_ = NullVector(right_nulls);
  // H&Z 15.9: F21 = [e2]x [T1, T2, T3] e3, F31 = [e3]x [T1^T, T2^T, T3^T] e2.
  Eigen::Matrix3d te3, tte2;
  for (int i = 0; i < 3; ++i) {
    te3.col(i) = slices_[i] * e3_;
    tte2.col(i) = slices_[i].transpose() * e2_;
  }
  F21_ = Skew(e2_) * te3;
  F31_ = Skew(e3_) * tte2;
  P2_ << te3, e2_;
  P3_ << (e3_ * e3_.transpose() - Eigen::Matrix3d::Identity()) * tte2, e3_;
}

TrifocalTensor TrifocalTensor::FromRelativePoses(const Eigen::Matrix3d& R21, const Eigen::Vector3d& t21,
                                                 const Eigen::Matrix3d& R31, const Eigen::Vector3d& t31) {
  std::array<Eigen::Matrix3d, 3> slices;
  for (int i = 0; i < 3; ++i) slices[i] = R21.col(i) * t31.transpose() - t21 * R31.col(i).transpose();
  return TrifocalTensor(slices);
}

Eigen::Matrix<double, 27, 1> TrifocalTensor::Normalized() const {
  Vector27d t;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) t(9 * i + 3 * j + k) = slices_[i](j, k);
  const double norm = t.norm();
  if (norm == 0) return t;
  Eigen::Index largest = 0;
  t.cwiseAbs().maxCoeff(&largest);
  return t / (t(largest) > 0 ? norm : -norm);
}

bool TrifocalTensor::TransferToThird(const Eigen::Vector2d& x1, const Eigen::Vector2d& x2, Eigen::Vector2d* x3) const {
  const Eigen::Vector3d h1 = x1.homogeneous();
  const Eigen::Vector3d l2 = PerpendicularLineThrough(F21_ * h1, x2);
  // H&Z 15.2.2: x3^k = x1^i l2_j T_i^{jk}.
  Eigen::Vector3d h3 = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) h3 += h1(i) * (slices_[i].transpose() * l2);
  return Dehomogenize(h3, x3);
}

bool TrifocalTensor::TransferToSecond(const Eigen::Vector2d& x1, const Eigen::Vector2d& x3, Eigen::Vector2d* x2) const {
  const Eigen::Vector3d h1 = x1.homogeneous();
  const Eigen::Vector3d l3 = PerpendicularLineThrough(F31_ * h1, x3);
  // x2^j = x1^i l3_k T_i^{jk}.
  Eigen::Vector3d h2 = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) h2 += h1(i) * (slices_[i] * l3);
  return Dehomogenize(h2, x2);
}

double TrifocalTensor::TransferError(const PointTriple& p) const {
  Eigen::Vector2d x2, x3;
  if (!TransferToThird(p.x1, p.x2, &x3) || !TransferToSecond(p.x1, p.x3, &x2))
    return std::numeric_limits<double>::infinity();
  return std::max((x3 - p.x3).norm(), (x2 - p.x2).norm());
}

double TrifocalTensor::ReprojectionError(const PointTriple& p) const {
  static const Eigen::Matrix<double, 3, 4> kP1 = Eigen::Matrix<double, 3, 4>::Identity();
  const std::array<const Eigen::Matrix<double, 3, 4>*, 3> cameras{&kP1, &P2_, &P3_};
  const std::array<const Eigen::Vector2d*, 3> points{&p.x1, &p.x2, &p.x3};
  // DLT: x cross (P X) = 0 gives two independent rows per view; the cameras are projective, so
  // each row is scaled to unit norm to keep one view from outweighing the others.
  Eigen::Matrix<double, 6, 4> a;
  for (int v = 0; v < 3; ++v) {
    const Eigen::Matrix<double, 3, 4>& P = *cameras[v];
    a.row(2 * v) = points[v]->x() * P.row(2) - P.row(0);
    a.row(2 * v + 1) = points[v]->y() * P.row(2) - P.row(1);
    for (int r = 2 * v; r < 2 * v + 2; ++r) {
      const double norm = a.row(r).norm();
      if (norm > 0) a.row(r) /= norm;
    }
  }
  Eigen::JacobiSVD<Eigen::Matrix<double, 6, 4>> svd(a, Eigen::ComputeFullV);
  const Eigen::Vector4d x = svd.matrixV().col(3);
  double worst = 0;
  for (int v = 0; v < 3; ++v) {
    Eigen::Vector2d projected;
    if (!Dehomogenize(*cameras[v] * x, &projected)) return std::numeric_limits<double>::infinity();
    worst = std::max(worst, (projected - *points[v]).norm());
  }
  return worst;
}

bool EstimateTrifocalLinear(const std::vector<PointTriple>& triples, TrifocalTensor* tensor) {
  const int n = static_cast<int>(triples.size());
  if (n < TrifocalEstimator::kMinimalSample)
    throw Error("trifocal tensor", "needs at least 7 point triples, got " + std::to_string(n));
  std::array<std::vector<Eigen::Vector2d>, 3> views;
  for (const auto& t : triples) {
    if (!t.x1.allFinite() || !t.x2.allFinite() || !t.x3.allFinite()) return false;
    views[0].push_back(t.x1);
    views[1].push_back(t.x2);
    views[2].push_back(t.x3);
  }
  std::array<Eigen::Matrix3d, 3> h;
  for (int v = 0; v < 3; ++v)
    if (!Normalization(views[v], &h[v])) return false;

  // The incidence [x2]x (sum_i x1^i T_i) [x3]x = 0_3x3 (H&Z 16.1) is linear in T: entry (s, t) is
  // sum_ijk x1^i [x2]x(s, j) [x3]x(k, t) T_i^{jk}. Rows s, t in {0, 1} are the 4 independent ones
  // (the third row and column of a skew matrix of a finite point follow from the first two).
  Eigen::MatrixXd a(4 * n, 27);
  for (int p = 0; p < n; ++p) {
    const Eigen::Vector3d x1 = h[0] * views[0][p].homogeneous();
    const Eigen::Matrix3d s2 = Skew(h[1] * views[1][p].homogeneous());
    const Eigen::Matrix3d s3 = Skew(h[2] * views[2][p].homogeneous());
    for (int s = 0; s < 2; ++s)
      for (int t = 0; t < 2; ++t)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) a(4 * p + 2 * s + t, 9 * i + 3 * j + k) = x1(i) * s2(s, j) * s3(k, t);
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
  const Eigen::VectorXd& sv = svd.singularValues();
  // 7 triples give 28 equations of rank 26: a second (near-)zero singular value means a pencil
  // of solutions, i.e. a degenerate configuration (points on a line, a plane seen by all views).
  if (!(sv(0) > 0) || sv(25) < 1e-9 * sv(0)) return false;
  const TrifocalTensor linear(SlicesOf(svd.matrixV().col(26)));

  // Algebraic minimization (H&Z 16.3): a valid tensor is T_i = a_i e3^T - e2 b_i^T, linear in the
  // 18 entries of a and b once the epipoles are fixed: t = E p. Minimizing |A t| subject to
  // |t| = 1 over the column space of E gives the closest valid tensor in the algebraic error,
  // which the 27 free entries of the linear solution are not, and which transfer needs to be
  // consistent in both directions.
  const Eigen::Vector3d& e2 = linear.epipole2();
  const Eigen::Vector3d& e3 = linear.epipole3();
  Eigen::Matrix<double, 27, 18> e = Eigen::Matrix<double, 27, 18>::Zero();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) {
        e(9 * i + 3 * j + k, 3 * i + j) += e3(k);
        e(9 * i + 3 * j + k, 9 + 3 * i + k) -= e2(j);
      }
  Eigen::JacobiSVD<Eigen::Matrix<double, 27, 18>> svd_e(e, Eigen::ComputeFullU);
  // (a_i + e2 c_i, b_i + e3 c_i) gives the same tensor: E has rank 15, not 18.
  int rank = 0;
  while (rank < 18 && svd_e.singularValues()(rank) > 1e-10 * svd_e.singularValues()(0)) ++rank;
  const Eigen::MatrixXd u = svd_e.matrixU().leftCols(rank);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd_au(a * u, Eigen::ComputeFullV);
  const Eigen::VectorXd t_hat = u * svd_au.matrixV().col(rank - 1);
  const std::array<Eigen::Matrix3d, 3> normalized = SlicesOf(t_hat);

  // Denormalize. Points map as x^ = H x and lines as l^ = H^-T l; the incidence
  // x1^i l2_j l3_k T_i^{jk} = 0 is invariant when T_i = sum_r H1(r, i) H2^-1 T^_r H3^-T.
  const Eigen::Matrix3d h2_inv = h[1].inverse();
  const Eigen::Matrix3d h3_inv_t = h[2].inverse().transpose();
  std::array<Eigen::Matrix3d, 3> slices;
  for (int i = 0; i < 3; ++i) {
    slices[i].setZero();
    for (int r = 0; r < 3; ++r) slices[i] += h[0](r, i) * (h2_inv * normalized[r] * h3_inv_t);
  }
  *tensor = TrifocalTensor(slices);
  return true;
}

std::vector<TrifocalTensor> TrifocalEstimator::Estimate(const std::vector<PointTriple>& data) const {
  TrifocalTensor tensor;
  if (!EstimateTrifocalLinear(data, &tensor)) return {};
  return {tensor};
}

void TrifocalEstimator::Residuals(const std::vector<PointTriple>& data, const TrifocalTensor& model,
                                  std::vector<double>* residuals) const {
  residuals->resize(data.size());
  for (size_t i = 0; i < data.size(); ++i) (*residuals)[i] = model.ReprojectionError(data[i]);
}

}  // namespace odvr::tracking
