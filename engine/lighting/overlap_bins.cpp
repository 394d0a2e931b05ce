#include "engine/lighting/overlap_bins.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <mutex>

#include "core/error.h"
#include "core/parallel.h"
#include "engine/lighting/sg.h"
#include "engine/sphere/equirect.h"
#include "engine/sphere/healpix.h"

namespace odvr::lighting {
namespace {

// ln(sinh(r)/r), finite for every r ≥ 0 (sinh overflows beyond r ≈ 710; λ reaches 1e4).
double LogSinhc(double r) {
  if (r < 1e-4) return r * r / 6;
  return r + std::log1p(-std::exp(-2 * r)) - std::log(2 * r);
}

// ln of ∫G_a G_b at angle θ between the axes over its value at θ = 0 (≤ 0).
double LogRelativeOverlap(double lambda_a, double lambda_b, double cos_theta) {
  const double r2 = lambda_a * lambda_a + lambda_b * lambda_b + 2 * lambda_a * lambda_b * cos_theta;
  const double r = std::sqrt(std::max(0.0, r2));
  const double aligned = lambda_a + lambda_b;
  return (LogSinhc(r) - r) - (LogSinhc(aligned) - aligned) + (r - aligned);
}

}  // namespace

void OverlapBinOptions::Check() const {
  if (lighting_levels < 1 || lighting_levels > 6) throw Error("overlap bins", "lighting levels must be 1..6");
  if (!(min_retention > 0 && min_retention < 1)) throw Error("overlap bins", "min retention must be in (0, 1)");
  if (!(cutoff > 0 && cutoff < 1)) throw Error("overlap bins", "cutoff must be in (0, 1)");
  if (bin_lambdas.empty()) throw Error("overlap bins", "needs at least one bin lobe size");
  for (std::size_t i = 0; i < bin_lambdas.size(); ++i)
    if (!(bin_lambdas[i] > 0) || (i > 0 && bin_lambdas[i] <= bin_lambdas[i - 1]))
      throw Error("overlap bins", "bin lobe sizes must be positive and increasing");
}

double OverlapBinLevel::mean_list_length() const {
  return bins() > 0 ? static_cast<double>(srbfs.size()) / bins() : 0.0;
}

std::size_t OverlapBinLevel::bytes() const { return sizeof(int) * (begin.size() + srbfs.size()); }

glm::dvec3 OverlapBinDirection(int t, int p, int n) {
  const double theta = kPi * t / n, phi = kPi * p / n;
  return {std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi)};
}

int OverlapBins::DepthFor(double lambda, int lighting_levels, double min_retention) {
  int depth = 0;
  for (int s = 1; s < lighting_levels; ++s)
    if (lambda / (sphere::Healpix(s).Lambda() + lambda) >= min_retention) depth = s;
  return depth;
}

std::shared_ptr<const OverlapBins> OverlapBins::Shared(const OverlapBinOptions& options) {
  constexpr std::size_t kKept = 8;
  static std::mutex mutex;
  static std::vector<std::shared_ptr<const OverlapBins>> kept;  // oldest first
  const std::lock_guard<std::mutex> lock(mutex);
  for (const auto& bins : kept)
    if (bins->options() == options) return bins;
  auto bins = std::make_shared<const OverlapBins>(options);
  if (kept.size() == kKept) kept.erase(kept.begin());
  kept.push_back(bins);
  return bins;
}

OverlapBins::OverlapBins(OverlapBinOptions options) : options_(std::move(options)) {
  options_.Check();
  const auto start = std::chrono::steady_clock::now();
  ThreadPool pool(0);

  // Every lighting SRBF once, in global order.
  struct Srbf {
    glm::dvec3 axis;
    int level;
  };
  std::vector<Srbf> all;
  for (int s = 0; s < options_.lighting_levels; ++s) {
    const auto& hp = sphere::Healpix(s);
    for (int i = 0; i < hp.size(); ++i) all.push_back({hp.centre(i), s});
  }
  const double log_cutoff = std::log(options_.cutoff);

  const auto& lambdas = options_.bin_lambdas;
  for (std::size_t k = 0; k < lambdas.size(); ++k) {
    OverlapBinLevel level;
    level.lambda = lambdas[k];
    const double spacing = HalfValueAngleForLambda(level.lambda) / 2;
    level.n = std::max(4, static_cast<int>(std::ceil(kPi / spacing)));
    level.max_level = k + 1 < lambdas.size()
                          ? DepthFor(lambdas[k + 1], options_.lighting_levels, options_.min_retention)
                          : options_.lighting_levels - 1;
    // Any direction lies within this angle of its nearest node: half the diagonal of a cell at
    // the equator is (π/n)/√2; φ steps only shrink towards the poles.
    const double cell_radius = 0.75 * kPi / level.n;
    // The overlap falls monotonically with the angle, so per lighting level one angle bounds it:
    // found by bisection, then each test is a dot product.
    std::vector<double> cos_limit(static_cast<std::size_t>(options_.lighting_levels), 1.0);
    for (int s = 0; s <= level.max_level; ++s) {
      const double ls = sphere::Healpix(s).Lambda();
      double lo = 0, hi = kPi;
      if (LogRelativeOverlap(ls, level.lambda, -1.0) >= log_cutoff) {
        lo = kPi;
      } else {
        for (int it = 0; it < 60; ++it) {
          const double mid = 0.5 * (lo + hi);
          (LogRelativeOverlap(ls, level.lambda, std::cos(mid)) >= log_cutoff ? lo : hi) = mid;
        }
      }
      cos_limit[static_cast<std::size_t>(s)] = std::cos(std::min(kPi, lo + cell_radius));
    }
    const int bins = level.bins();
    std::vector<std::vector<int>> lists(static_cast<std::size_t>(bins));
    pool.ParallelFor(
        bins,
        [&](long begin, long end) {
          for (long b = begin; b < end; ++b) {
            const int t = static_cast<int>(b / (2 * level.n)), p = static_cast<int>(b % (2 * level.n));
            const glm::dvec3 d = OverlapBinDirection(t, p, level.n);
            auto& list = lists[static_cast<std::size_t>(b)];
            for (std::size_t g = 0; g < all.size(); ++g) {
              if (all[g].level > level.max_level) break;  // `all` is ordered by level
              if (glm::dot(d, all[g].axis) >= cos_limit[static_cast<std::size_t>(all[g].level)])
                list.push_back(static_cast<int>(g));
            }
          }
        },
        16);
    level.begin.assign(static_cast<std::size_t>(bins) + 1, 0);
    for (int b = 0; b < bins; ++b)
      level.begin[static_cast<std::size_t>(b) + 1] =
          level.begin[static_cast<std::size_t>(b)] + static_cast<int>(lists[static_cast<std::size_t>(b)].size());
    level.srbfs.reserve(static_cast<std::size_t>(level.begin.back()));
    for (const auto& list : lists) level.srbfs.insert(level.srbfs.end(), list.begin(), list.end());
    levels_.push_back(std::move(level));
  }
  build_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

const OverlapBinLevel& OverlapBins::LevelFor(double lambda) const {
  std::size_t k = 0;
  while (k + 1 < levels_.size() && levels_[k + 1].lambda <= lambda) ++k;
  return levels_[k];
}

int OverlapBins::BinOf(const OverlapBinLevel& level, const glm::dvec3& direction) const {
  const glm::dvec3 d = glm::normalize(direction);
  const double theta = std::acos(std::clamp(d.y, -1.0, 1.0));
  double phi = std::atan2(-d.z, d.x);
  if (phi < 0) phi += 2 * kPi;
  const int t = std::clamp(static_cast<int>(std::lround(theta * level.n / kPi)), 0, level.n);
  const int p = static_cast<int>(std::lround(phi * level.n / kPi)) % (2 * level.n);
  return t * 2 * level.n + p;
}

std::span<const int> OverlapBins::Query(const glm::dvec3& direction, double lambda) const {
  const OverlapBinLevel& level = LevelFor(lambda);
  const int b = BinOf(level, direction);
  const auto begin = static_cast<std::size_t>(level.begin[static_cast<std::size_t>(b)]);
  const auto end = static_cast<std::size_t>(level.begin[static_cast<std::size_t>(b) + 1]);
  return std::span<const int>(level.srbfs).subspan(begin, end - begin);
}

int OverlapBins::MaxLevel(double lambda, double share) const {
  if (!(share > 0)) return 0;
  return DepthFor(lambda, options_.lighting_levels, options_.min_retention / share);
}

std::size_t OverlapBins::bytes() const {
  std::size_t total = 0;
  for (const auto& l : levels_) total += l.bytes();
  return total;
}

}  // namespace odvr::lighting
