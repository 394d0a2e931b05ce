#pragma once
// One generic RANSAC for every estimator of the tracker (STYLE.md, after COLMAP's
// RANSAC<Estimator>): the trifocal tensor, a fundamental matrix or the rig's relative pose plug
// in as estimators and are tested alone; sampling, the adaptive stopping rule and the local
// refinement live here once.
//
// An Estimator provides
//   using Datum = ...;                      // one correspondence
//   using Model = ...;
//   static constexpr int kMinimalSample;    // data one Estimate needs at least
//   // Models consistent with `data` (kMinimalSample or more; more = least squares). Empty when
//   // the sample is degenerate.
//   std::vector<Model> Estimate(const std::vector<Datum>& data) const;
//   // One residual per datum, in the unit of RansacOptions::max_residual.
//   void Residuals(const std::vector<Datum>& data, const Model& model, std::vector<double>* r) const;
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "core/error.h"

namespace odvr::tracking {

struct RansacOptions {
  double max_residual = 1.0;  // inlier threshold, in the estimator's residual unit
  double confidence = 0.999;  // probability that one all-inlier sample was drawn when we stop
  int min_iterations = 0;
  int max_iterations = 10000;
  std::uint64_t random_seed = 0;   // the same seed draws the same samples
  bool deterministic = true;       // false: seed from std::random_device instead
  bool local_optimization = true;  // re-estimate on all inliers of each new best model
  // Refits per LO run; a run stops early once a refit no longer lowers the cost. Each refit
  // typically gains a few inliers: on the trifocal test (400 triples, 30 % outliers) 4 steps
  // left the tensor 0.2-0.85 px from the truth, 10 reach the all-inlier fit (0.2-0.3 px).
  int local_optimization_steps = 10;

  // Throws odvr::Error naming the first bad parameter.
  void Check() const;
};

template <typename Model>
struct RansacReport {
  bool success = false;  // a model with at least kMinimalSample inliers was found
  Model model{};
  int iterations = 0;
  int num_inliers = 0;
  int num_data = 0;
  std::vector<char> inlier_mask;  // one per datum
  int local_optimizations = 0;    // LO steps that improved the best model

  double inlier_ratio() const { return num_data > 0 ? static_cast<double>(num_inliers) / num_data : 0.0; }
  std::string BriefReport() const {
    return std::string(success ? "ransac ok" : "ransac FAILED") + ": " + std::to_string(num_inliers) + "/" +
           std::to_string(num_data) + " inliers, " + std::to_string(iterations) + " iterations, " +
           std::to_string(local_optimizations) + " LO improvements";
  }
};

// Iterations for `confidence` that one sample of `sample_size` is all inliers at `inlier_ratio`
// (Fischler & Bolles): N = log(1 - p) / log(1 - w^s).
int RansacIterationsNeeded(double inlier_ratio, int sample_size, double confidence, int max_iterations);

template <typename Estimator>
class Ransac {
 public:
  using Datum = typename Estimator::Datum;
  using Model = typename Estimator::Model;
  using Report = RansacReport<Model>;

  explicit Ransac(const RansacOptions& options, Estimator estimator = Estimator())
      : options_(options), estimator_(std::move(estimator)) {
    options_.Check();
  }

  Report Estimate(const std::vector<Datum>& data) const {
    Report report;
    const int n = static_cast<int>(data.size());
    constexpr int kSample = Estimator::kMinimalSample;
    report.num_data = n;
    report.inlier_mask.assign(n, 0);
    if (n < kSample) return report;

    std::mt19937_64 rng(options_.deterministic ? options_.random_seed : std::random_device{}());
    std::vector<int> indices(n);
    std::iota(indices.begin(), indices.end(), 0);
    std::vector<Datum> sample(kSample);
    std::vector<double> residuals;

    Score best;
    int needed = options_.max_iterations;
    int it = 0;
    for (; it < options_.max_iterations && (it < options_.min_iterations || it < needed); ++it) {
      // Partial Fisher-Yates: the first kSample indices become a uniform sample without repeats.
      for (int i = 0; i < kSample; ++i) {
        std::uniform_int_distribution<int> pick(i, n - 1);
        std::swap(indices[i], indices[pick(rng)]);
        sample[i] = data[indices[i]];
      }
      for (const Model& model : estimator_.Estimate(sample)) {
        Score score = Evaluate(data, model, &residuals);
        if (!(score > best)) continue;
        best = std::move(score);
        best.model = model;
        if (options_.local_optimization) LocalOptimize(data, &best, &residuals, &report);
        needed = RansacIterationsNeeded(static_cast<double>(best.inliers) / n, kSample, options_.confidence,
                                        options_.max_iterations);
      }
    }
    report.iterations = it;
    if (best.inliers < kSample) return report;
    report.success = true;
    report.model = best.model;
    report.num_inliers = best.inliers;
    estimator_.Residuals(data, best.model, &residuals);
    for (int i = 0; i < n; ++i) report.inlier_mask[i] = Inlier(residuals[i]) ? 1 : 0;
    return report;
  }

  const RansacOptions& options() const { return options_; }

 private:
  // MSAC's score (Torr & Zisserman 2000): inliers cost their squared residual, outliers the
  // squared threshold. Counting inliers alone ranks a loose model that grazes a few outliers
  // above the tighter refit LO produces; the truncated cost prefers the tighter fit.
  struct Score {
    int inliers = 0;
    double cost = std::numeric_limits<double>::infinity();
    Model model{};
    bool operator>(const Score& o) const { return cost < o.cost; }
  };

  bool Inlier(double r) const { return std::isfinite(r) && r <= options_.max_residual; }

  Score Evaluate(const std::vector<Datum>& data, const Model& model, std::vector<double>* residuals) const {
    estimator_.Residuals(data, model, residuals);
    Score s;
    s.cost = 0;
    const double t2 = options_.max_residual * options_.max_residual;
    for (double r : *residuals) {
      if (Inlier(r)) {
        ++s.inliers;
        s.cost += r * r;
      } else {
        s.cost += t2;
      }
    }
    return s;
  }

  // LO-RANSAC (Chum et al. 2003), simplified: refit on every inlier of the best model and keep
  // the refit while it scores better. A minimal sample carries its noise into the model; the
  // least-squares refit on the whole consensus set does not, and usually gains inliers.
  void LocalOptimize(const std::vector<Datum>& data, Score* best, std::vector<double>* residuals,
                     Report* report) const {
    std::vector<Datum> inliers;
    for (int step = 0; step < options_.local_optimization_steps; ++step) {
      estimator_.Residuals(data, best->model, residuals);
      inliers.clear();
      for (size_t i = 0; i < data.size(); ++i)
        if (Inlier((*residuals)[i])) inliers.push_back(data[i]);
      if (static_cast<int>(inliers.size()) <= Estimator::kMinimalSample) return;
      bool improved = false;
      for (const Model& model : estimator_.Estimate(inliers)) {
        Score score = Evaluate(data, model, residuals);
        if (score > *best) {
          *best = std::move(score);
          best->model = model;
          improved = true;
        }
      }
      if (!improved) return;
      ++report->local_optimizations;
    }
  }

  RansacOptions options_;
  Estimator estimator_;
};

}  // namespace odvr::tracking
