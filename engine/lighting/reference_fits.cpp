#include "engine/lighting/reference_fits.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>

#include "core/error.h"
#include "core/parallel.h"
#include "engine/lighting/residual_transform.h"
#include "engine/lighting/sg.h"
#include "engine/sphere/equirect.h"
#include "engine/sphere/healpix.h"

namespace odvr::lighting {
namespace {

// Normalized associated Legendre K_l^m P_l^m(x) for 0 ≤ m ≤ l ≤ order, index l(l+1)/2 + m
// (no Condon–Shortley phase: projection and reconstruction use the same functions).
void Legendre(int order, double x, std::vector<double>* out) {
  const auto idx = [](int l, int m) { return static_cast<std::size_t>(l * (l + 1) / 2 + m); };
  out->assign(idx(order, order) + 1, 0.0);
  std::vector<double> p(out->size());
  const double s = std::sqrt(std::max(0.0, 1 - x * x));
  double pmm = 1;
  for (int m = 0; m <= order; ++m) {
    if (m > 0) pmm *= (2 * m - 1) * s;
    p[idx(m, m)] = pmm;
    if (m + 1 <= order) p[idx(m + 1, m)] = x * (2 * m + 1) * pmm;
    for (int l = m + 2; l <= order; ++l)
      p[idx(l, m)] = ((2 * l - 1) * x * p[idx(l - 1, m)] - (l + m - 1) * p[idx(l - 2, m)]) / (l - m);
  }
  for (int l = 0; l <= order; ++l)
    for (int m = 0; m <= l; ++m) {
      // (l−m)!/(l+m)! as a product, so it stays finite for the orders used here.
      double ratio = 1;
      for (int k = l - m + 1; k <= l + m; ++k) ratio /= k;
      (*out)[idx(l, m)] = std::sqrt((2 * l + 1) / (4 * kPi) * ratio) * p[idx(l, m)];
    }
}

}  // namespace

SgLighting LeastSquaresSgFit(const sphere::EquirectImage& image, int levels, LeastSquaresReport* report) {
  if (levels < 1 || levels > 6) throw Error("least-squares fit", "levels must be 1..6");
  const auto start = std::chrono::steady_clock::now();
  ThreadPool pool(0);

  // Basis: the constant, then every SRBF of levels 0..levels−1 in global order.
  std::vector<Sg> basis{Sg{{0, 1, 0}, 0.0, 1.0}};
  for (int s = 0; s < levels; ++s)
    for (const auto& c : sphere::Healpix(s).centres()) basis.push_back(Sg{c, sphere::Healpix(s).Lambda(), 1.0});
  const int n = static_cast<int>(basis.size());

  // Right side ∫ I B_i over the pixels of each cap (the transform's own overlap lists).
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 3);
  for (int row = 0; row < image.height; ++row) {
    const double da = sphere::EquirectPixelSolidAngle(row, image.width, image.height);
    for (int col = 0; col < image.width; ++col)
      for (int k = 0; k < 3; ++k) rhs(0, k) += da * image.at(col, row)[k];
  }
  int first = 1;
  for (int s = 0; s < levels; ++s) {
    const LevelTables t = BuildLevelTables(s, image.width, image.height, 1e-5, &pool);
    for (int c = 0; c + 1 < static_cast<int>(t.srbf_begin.size()); ++c)
      for (int e = t.srbf_begin[static_cast<std::size_t>(c)]; e < t.srbf_begin[static_cast<std::size_t>(c) + 1]; ++e) {
        const float* p = &image.rgb[3 * static_cast<std::size_t>(t.srbf_pixel[static_cast<std::size_t>(e)])];
        for (int k = 0; k < 3; ++k) rhs(first + c, k) += t.srbf_weight[static_cast<std::size_t>(e)] * p[k];
      }
    first += sphere::HealpixCount(s);
  }

  // Gram ∫ B_i B_j, closed form, sparse.
  std::vector<double> diag(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) diag[static_cast<std::size_t>(i)] = IntegralOfProduct(basis[i], basis[i]);
  std::vector<std::vector<std::pair<int, double>>> rows(static_cast<std::size_t>(n));
  pool.ParallelFor(
      n,
      [&](long begin, long end) {
        for (long i = begin; i < end; ++i)
          for (int j = 0; j <= i; ++j) {
            const double g = IntegralOfProduct(basis[static_cast<std::size_t>(i)], basis[static_cast<std::size_t>(j)]);
            if (g >= 1e-9 * std::sqrt(diag[static_cast<std::size_t>(i)] * diag[static_cast<std::size_t>(j)]))
              rows[static_cast<std::size_t>(i)].emplace_back(j, g);
          }
      },
      8);
  std::vector<Eigen::Triplet<double>> triplets;
  double trace = 0;
  for (int i = 0; i < n; ++i) trace += diag[static_cast<std::size_t>(i)];
  for (int i = 0; i < n; ++i)
    for (const auto& [j, g] : rows[static_cast<std::size_t>(i)]) {
      // A ridge of 1e-10 of the mean diagonal: the levels are nearly nested, so the Gram is close
      // to singular; this leaves the residual unchanged to far below the errors compared.
      const double v = i == j ? g + 1e-10 * trace / n : g;
      triplets.emplace_back(i, j, v);
      if (i != j) triplets.emplace_back(j, i, v);
    }
  Eigen::SparseMatrix<double> gram(n, n);
  gram.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(gram);
  if (solver.info() != Eigen::Success) throw Error("least-squares fit", "the Gram matrix could not be factored");
  const Eigen::MatrixXd mu = solver.solve(rhs);

  SgLighting model;
  model.constant = glm::vec3(mu(0, 0), mu(0, 1), mu(0, 2));
  first = 1;
  for (int s = 0; s < levels; ++s) {
    SgLevel level;
    level.level = s;
    level.lambda = sphere::Healpix(s).Lambda();
    for (int c = 0; c < sphere::HealpixCount(s); ++c) {
      level.indices.push_back(c);
      level.amplitudes.emplace_back(mu(first + c, 0), mu(first + c, 1), mu(first + c, 2));
    }
    first += sphere::HealpixCount(s);
    model.levels.push_back(std::move(level));
  }
  if (report) {
    report->unknowns = n;
    report->gram_nonzeros = static_cast<long>(gram.nonZeros());
    report->ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  }
  return model;
}

ShModel ProjectSphericalHarmonics(const sphere::EquirectImage& image, int order) {
  if (order < 0 || order > 32) throw Error("spherical harmonics", "order must be 0..32");
  ShModel sh;
  sh.order = order;
  const int count = (order + 1) * (order + 1);
  sh.coefficients.assign(static_cast<std::size_t>(count), glm::vec3(0));
  const int w = image.width;
  std::vector<double> cos_m(static_cast<std::size_t>((order + 1) * w)), sin_m(cos_m.size());
  for (int m = 0; m <= order; ++m)
    for (int col = 0; col < w; ++col) {
      const double lon = kPi * (1 - 2 * (col + 0.5) / w);  // φ of equirect.h
      cos_m[static_cast<std::size_t>(m * w + col)] = std::cos(m * lon);
      sin_m[static_cast<std::size_t>(m * w + col)] = std::sin(m * lon);
    }
  std::vector<double> legendre;
  std::vector<glm::dvec3> acc(static_cast<std::size_t>(count), glm::dvec3(0));
  for (int row = 0; row < image.height; ++row) {
    const double lat = kPi / 2 - kPi * (row + 0.5) / image.height;
    const double da = sphere::EquirectPixelSolidAngle(row, w, image.height);
    Legendre(order, std::sin(lat), &legendre);
    for (int m = 0; m <= order; ++m) {
      glm::dvec3 c(0), s(0);
      for (int col = 0; col < w; ++col) {
        const float* p = image.at(col, row);
        const glm::dvec3 v(p[0], p[1], p[2]);
        c += v * cos_m[static_cast<std::size_t>(m * w + col)];
        s += v * sin_m[static_cast<std::size_t>(m * w + col)];
      }
      for (int l = m; l <= order; ++l) {
        const double k = legendre[static_cast<std::size_t>(l * (l + 1) / 2 + m)] * da;
        if (m == 0) {
          acc[static_cast<std::size_t>(l * (l + 1))] += k * c;
        } else {
          acc[static_cast<std::size_t>(l * (l + 1) + m)] += std::sqrt(2.0) * k * c;
          acc[static_cast<std::size_t>(l * (l + 1) - m)] += std::sqrt(2.0) * k * s;
        }
      }
    }
  }
  for (int i = 0; i < count; ++i)
    sh.coefficients[static_cast<std::size_t>(i)] = glm::vec3(acc[static_cast<std::size_t>(i)]);
  return sh;
}

glm::vec3 ShModel::Evaluate(const glm::dvec3& direction) const {
  const glm::dvec3 d = glm::normalize(direction);
  const double phi = std::atan2(-d.z, d.x);
  std::vector<double> legendre;
  Legendre(order, d.y, &legendre);
  glm::dvec3 sum(0);
  for (int l = 0; l <= order; ++l)
    for (int m = 0; m <= l; ++m) {
      const double k = legendre[static_cast<std::size_t>(l * (l + 1) / 2 + m)];
      if (m == 0) {
        sum += k * glm::dvec3(coefficients[static_cast<std::size_t>(l * (l + 1))]);
      } else {
        sum += std::sqrt(2.0) * k *
               (std::cos(m * phi) * glm::dvec3(coefficients[static_cast<std::size_t>(l * (l + 1) + m)]) +
                std::sin(m * phi) * glm::dvec3(coefficients[static_cast<std::size_t>(l * (l + 1) - m)]));
      }
    }
  return glm::vec3(sum);
}

sphere::EquirectImage ShModel::Reconstruct(int width, int height) const {
  sphere::EquirectImage out(width, height);
  ThreadPool pool(0);
  pool.ParallelFor(
      height,
      [&](long begin, long end) {
        std::vector<double> legendre;
        for (long row = begin; row < end; ++row) {
          const double lat = kPi / 2 - kPi * (static_cast<double>(row) + 0.5) / height;
          Legendre(order, std::sin(lat), &legendre);
          for (int col = 0; col < width; ++col) {
            const double phi = kPi * (1 - 2 * (col + 0.5) / width);
            glm::dvec3 sum(0);
            for (int m = 0; m <= order; ++m) {
              const double cm = std::cos(m * phi), sm = std::sin(m * phi);
              for (int l = m; l <= order; ++l) {
                const double k = legendre[static_cast<std::size_t>(l * (l + 1) / 2 + m)];
                if (m == 0)
                  sum += k * glm::dvec3(coefficients[static_cast<std::size_t>(l * (l + 1))]);
                else
                  sum += std::sqrt(2.0) * k *
                         (cm * glm::dvec3(coefficients[static_cast<std::size_t>(l * (l + 1) + m)]) +
                          sm * glm::dvec3(coefficients[static_cast<std::size_t>(l * (l + 1) - m)]));
              }
            }
            float* p = out.at(col, static_cast<int>(row));
            p[0] = static_cast<float>(sum.x);
            p[1] = static_cast<float>(sum.y);
            p[2] = static_cast<float>(sum.z);
          }
        }
      },
      1);
  return out;
}

}  // namespace odvr::lighting
