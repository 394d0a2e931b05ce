#include "tracking/ransac.h"

namespace odvr::tracking {

void RansacOptions::Check() const {
  if (!(max_residual > 0) || !std::isfinite(max_residual)) throw Error("ransac max_residual", "must be > 0");
  if (!(confidence > 0 && confidence < 1)) throw Error("ransac confidence", "must be in (0, 1)");
  if (min_iterations < 0) throw Error("ransac min_iterations", "must be >= 0");
  if (max_iterations < 1 || max_iterations < min_iterations)
    throw Error("ransac max_iterations", "must be >= 1 and >= min_iterations");
  if (local_optimization_steps < 0) throw Error("ransac local_optimization_steps", "must be >= 0");
}

int RansacIterationsNeeded(double inlier_ratio, int sample_size, double confidence, int max_iterations) {
  const double all_inliers = std::pow(std::clamp(inlier_ratio, 0.0, 1.0), sample_size);
  if (all_inliers >= 1.0) return 1;
  // log1p keeps tiny all-inlier probabilities (w^s ~ 1e-12) from rounding 1 - w^s to 1.
  const double denominator = std::log1p(-all_inliers);
  if (!(denominator < 0)) return max_iterations;
  const double n = std::ceil(std::log1p(-confidence) / denominator);
  return n >= max_iterations ? max_iterations : std::max(1, static_cast<int>(n));
}

}  // namespace odvr::tracking
