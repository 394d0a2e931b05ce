#include "capture/stitcher.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "capture/stitcher_gpu.h"
#include "engine/core/error.h"
#include "engine/core/parallel.h"
#include "engine/image/image_io.h"
#include "engine/sphere/equirect.h"

namespace odvr::capture {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// Weight of a sample at (u, v) of a w x h image: a tent in each direction, 1 at the centre and 0
// on the image's outer edge, so a camera fades out before its content ends (no visible seam).
float FeatherWeight(double u, double v, int w, int h) {
  const double tu = std::min(u + 0.5, w - 0.5 - u) / (0.5 * w);
  const double tv = std::min(v + 0.5, h - 0.5 - v) / (0.5 * h);
  return static_cast<float>(std::clamp(tu, 0.0, 1.0) * std::clamp(tv, 0.0, 1.0));
}

const std::array<float, 256>& SrgbTable() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[static_cast<std::size_t>(i)] = image::SrgbToLinear(i / 255.0f);
    return t;
  }();
  return table;
}

// A camera frame linearized to float RGB (the order the output uses).
struct LinearImage {
  int width = 0, height = 0;
  std::vector<float> rgb;

  // Bilinear at OpenCV pixel coordinates (centres at integers), edges clamped; the GPU shader
  // stitch_warp.comp computes the same expression.
  void Sample(float u, float v, float* out) const {
    const float fu = std::floor(u), fv = std::floor(v);
    const float au = u - fu, av = v - fv;
    const int x0 = std::clamp(static_cast<int>(fu), 0, width - 1),
              x1 = std::clamp(static_cast<int>(fu) + 1, 0, width - 1);
    const int y0 = std::clamp(static_cast<int>(fv), 0, height - 1),
              y1 = std::clamp(static_cast<int>(fv) + 1, 0, height - 1);
    const float* p00 = &rgb[3 * (static_cast<std::size_t>(y0) * width + x0)];
    const float* p10 = &rgb[3 * (static_cast<std::size_t>(y0) * width + x1)];
    const float* p01 = &rgb[3 * (static_cast<std::size_t>(y1) * width + x0)];
    const float* p11 = &rgb[3 * (static_cast<std::size_t>(y1) * width + x1)];
    for (int k = 0; k < 3; ++k) {
      const float top = p00[k] + au * (p10[k] - p00[k]);
      const float bottom = p01[k] + au * (p11[k] - p01[k]);
      out[k] = top + av * (bottom - top);
    }
  }
};

}  // namespace

void StitchOptions::Check() const {
  if (width < 4 || height < 2 || width > 32768 || height > 16384)
    throw UsageError("--size", "output size " + std::to_string(width) + "x" + std::to_string(height) +
                                   " is out of range (4x2 .. 32768x16384)");
  if (!(scene_distance_m >= 0) || !std::isfinite(scene_distance_m))
    throw UsageError("scene_distance_m", "must be 0 (infinity) or a positive distance");
  if (!(gain_sigma_n > 0 && gain_sigma_g > 0)) throw UsageError("gain_sigma", "sigmas must be positive");
  if (!(min_gain > 0 && max_gain >= min_gain)) throw UsageError("min_gain/max_gain", "need 0 < min_gain <= max_gain");
  if (gain_sample_step < 1) throw UsageError("gain_sample_step", "must be at least 1");
  if (!(black_level >= 0)) throw UsageError("black_level", "must not be negative");
  if (threads < 0) throw UsageError("threads", "must not be negative");
}

StitchLut BuildStitchLut(const Rig& rig, const StitchOptions& options) {
  options.Check();
  if (rig.cameras.empty()) throw Error(rig.path.string(), "rig has no cameras");
  if (rig.camera_count() > kMaxStitchCameras)
    throw Error(rig.path.string(), "rig has " + std::to_string(rig.camera_count()) + " cameras; the stitcher takes " +
                                       std::to_string(kMaxStitchCameras) + " at most");
  StitchLut lut;
  lut.width = options.width;
  lut.height = options.height;
  lut.cameras = rig.camera_count();
  struct CamGeom {
    Eigen::Matrix3d cam_from_rig;
    Eigen::Vector3d position;
  };
  std::vector<CamGeom> geom;
  for (const auto& c : rig.cameras)
    geom.push_back({c.rig_from_cam.topLeftCorner<3, 3>().transpose(), c.rig_from_cam.topRightCorner<3, 1>()});

  const double distance = options.scene_distance_m;
  std::vector<std::vector<StitchLut::Entry>> rows(static_cast<std::size_t>(lut.height));
  std::vector<std::uint8_t> counts(lut.pixel_count(), 0);
  ThreadPool pool(options.threads);
  pool.ParallelFor(
      lut.height,
      [&](long begin, long end) {
        for (long row = begin; row < end; ++row) {
          auto& out = rows[static_cast<std::size_t>(row)];
          for (int col = 0; col < lut.width; ++col) {
            const glm::dvec3 d = sphere::EquirectPixelDirection(col, static_cast<int>(row), lut.width, lut.height);
            const Eigen::Vector3d bearing_rig = RigFromOdvr({d.x, d.y, d.z});
            std::uint8_t n = 0;
            for (int c = 0; c < lut.cameras; ++c) {
              const CamGeom& g = geom[static_cast<std::size_t>(c)];
              // At infinity only the rotation matters; at a finite distance the ray from the rig
              // centre meets the scene sphere, and each camera looks at that point from its own centre.
              const Eigen::Vector3d p_cam =
                  distance > 0 ? Eigen::Vector3d(g.cam_from_rig * (distance * bearing_rig - g.position))
                               : Eigen::Vector3d(g.cam_from_rig * bearing_rig);
              const CameraModel& m = rig.cameras[static_cast<std::size_t>(c)].model;
              Eigen::Vector2d px;
              if (!m.Project(p_cam, &px) || !m.InImage(px)) continue;
              const float w = FeatherWeight(px.x(), px.y(), m.width(), m.height());
              if (w <= 0) continue;
              out.push_back({static_cast<float>(px.x()), static_cast<float>(px.y()), w, static_cast<std::uint32_t>(c)});
              ++n;
            }
            counts[static_cast<std::size_t>(row) * lut.width + col] = n;
          }
        }
      },
      1);
  lut.offsets.assign(lut.pixel_count() + 1, 0);
  std::size_t total = 0;
  for (const auto& r : rows) total += r.size();
  lut.entries.reserve(total);
  for (const auto& r : rows) lut.entries.insert(lut.entries.end(), r.begin(), r.end());
  for (std::size_t p = 0; p < lut.pixel_count(); ++p) lut.offsets[p + 1] = lut.offsets[p] + counts[p];
  const int step = options.gain_sample_step;
  for (int row = step / 2; row < lut.height; row += step)
    for (int col = step / 2; col < lut.width; col += step) {
      const std::size_t p = static_cast<std::size_t>(row) * lut.width + col;
      if (counts[p] >= 2) lut.gain_pixels.push_back(static_cast<std::uint32_t>(p));
    }
  return lut;
}

std::vector<double> SolveGains(const std::vector<std::vector<double>>& counts,
                               const std::vector<std::vector<double>>& means, const std::vector<bool>& usable,
                               const StitchOptions& options) {
  const int n = static_cast<int>(usable.size());
  // The data term is scaled by the mean overlap intensity, so that sigma_n is relative and the
  // balance against the prior does not depend on the scene's brightness.
  double mean_sum = 0, mean_count = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      if (i != j && usable[i] && usable[j] && counts[i][j] > 0) {
        mean_sum += counts[i][j] * means[i][j];
        mean_count += counts[i][j];
      }
  std::vector<double> gains(static_cast<std::size_t>(n), 1.0);
  if (mean_count == 0 || mean_sum <= 0) return gains;
  const double mean_intensity = mean_sum / mean_count;
  const double alpha = 1.0 / std::pow(options.gain_sigma_n * mean_intensity, 2);
  const double beta = 1.0 / std::pow(options.gain_sigma_g, 2);
  // Normal equations as in OpenCV's GainCompensator::singleFeed.
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  for (int i = 0; i < n; ++i) {
    if (!usable[i]) {
      a(i, i) = 1;
      b(i) = 1;
      continue;
    }
    for (int j = 0; j < n; ++j) {
      if (j == i || !usable[j] || counts[i][j] <= 0) continue;
      const double nij = counts[i][j];
      b(i) += beta * nij;
      a(i, i) += beta * nij + 2 * alpha * means[i][j] * means[i][j] * nij;
      a(i, j) -= 2 * alpha * means[i][j] * means[j][i] * nij;
    }
    if (a(i, i) == 0) {  // usable but overlapping no usable camera: nothing to say, keep 1
      a(i, i) = 1;
      b(i) = 1;
    }
  }
  const Eigen::VectorXd g = a.colPivHouseholderQr().solve(b);
  for (int i = 0; i < n; ++i)
    if (usable[i])
      gains[static_cast<std::size_t>(i)] =
          std::isfinite(g(i)) ? std::clamp(g(i), options.min_gain, options.max_gain) : 1.0;
  return gains;
}

namespace {

// One pull-push pyramid level: premultiplied RGB and coverage per pixel (4 floats).
struct Level {
  int width = 0, height = 0;
  std::vector<float> data;
  float* at(int x, int y) { return &data[4 * (static_cast<std::size_t>(y) * width + x)]; }
  const float* at(int x, int y) const { return &data[4 * (static_cast<std::size_t>(y) * width + x)]; }
};

// The coarse level's colour at fine pixel (x, y): bilinear, wrapping in longitude and clamped in
// latitude. shaders/stitch_push.comp evaluates the same expression.
void Upsample(const Level& coarse, int x, int y, float* out) {
  const float sx = (x + 0.5f) * 0.5f - 0.5f, sy = (y + 0.5f) * 0.5f - 0.5f;
  const float fx = std::floor(sx), fy = std::floor(sy);
  const float ax = sx - fx, ay = sy - fy;
  const int w = coarse.width, h = coarse.height;
  const int x0 = ((static_cast<int>(fx) % w) + w) % w, x1 = (x0 + 1) % w;
  const int y0 = std::clamp(static_cast<int>(fy), 0, h - 1), y1 = std::clamp(static_cast<int>(fy) + 1, 0, h - 1);
  for (int k = 0; k < 3; ++k) {
    const float top = coarse.at(x0, y0)[k] + ax * (coarse.at(x1, y0)[k] - coarse.at(x0, y0)[k]);
    const float bottom = coarse.at(x0, y1)[k] + ax * (coarse.at(x1, y1)[k] - coarse.at(x0, y1)[k]);
    out[k] = top + ay * (bottom - top);
  }
}

// Averages the (up to) 2x2 children of each coarse pixel; columns wrap around the seam.
Level Pull(const Level& fine) {
  Level c;
  c.width = (fine.width + 1) / 2;
  c.height = (fine.height + 1) / 2;
  c.data.assign(4 * static_cast<std::size_t>(c.width) * c.height, 0.f);
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      float sum[4] = {0, 0, 0, 0};
      int n = 0;
      for (int dy = 0; dy < 2; ++dy) {
        const int fy = 2 * y + dy;
        if (fy >= fine.height) continue;
        for (int dx = 0; dx < 2; ++dx) {
          const float* f = fine.at((2 * x + dx) % fine.width, fy);
          for (int k = 0; k < 4; ++k) sum[k] += f[k];
          ++n;
        }
      }
      for (int k = 0; k < 4; ++k) c.at(x, y)[k] = sum[k] / static_cast<float>(n);
    }
  return c;
}

}  // namespace

void FillUnseen(sphere::EquirectImage* image, const std::vector<std::uint8_t>& valid, ThreadPool* pool) {
  std::vector<Level> levels(1);
  levels[0].width = image->width;
  levels[0].height = image->height;
  levels[0].data.assign(4 * image->pixel_count(), 0.f);
  for (std::size_t p = 0; p < image->pixel_count(); ++p) {
    if (!valid[p]) continue;
    for (int k = 0; k < 3; ++k) levels[0].data[4 * p + k] = image->rgb[3 * p + k];
    levels[0].data[4 * p + 3] = 1;
  }
  while (levels.back().width > 1 || levels.back().height > 1) levels.push_back(Pull(levels.back()));
  // Top: un-premultiply. Then each level's filled colour is its own premultiplied content plus
  // the coarser filled colour for the coverage it lacks (Gortler's push with a = coverage).
  Level filled = levels.back();
  {
    float* t = filled.at(0, 0);
    const float a = t[3];
    for (int k = 0; k < 3; ++k) t[k] = a > 0 ? t[k] / a : 0.f;
  }
  for (int l = static_cast<int>(levels.size()) - 2; l >= 0; --l) {
    const Level& own = levels[static_cast<std::size_t>(l)];
    Level next;
    next.width = own.width;
    next.height = own.height;
    next.data.assign(own.data.size(), 0.f);
    auto rows = [&](long begin, long end) {
      for (long y = begin; y < end; ++y)
        for (int x = 0; x < own.width; ++x) {
          const float* o = own.at(x, static_cast<int>(y));
          float* dst = next.at(x, static_cast<int>(y));
          // A fully covered pixel keeps its own colour ((1 − 1)·up adds nothing), so the
          // upsample is skipped there; most of the finest level is covered.
          if (o[3] >= 1) {
            for (int k = 0; k < 3; ++k) dst[k] = o[k];
          } else {
            float up[3];
            Upsample(filled, x, static_cast<int>(y), up);
            for (int k = 0; k < 3; ++k) dst[k] = o[k] + (1 - o[3]) * up[k];
          }
          dst[3] = 1;
        }
    };
    if (pool) {
      pool->ParallelFor(own.height, rows, 8);
    } else {
      rows(0, own.height);
    }
    filled = std::move(next);
  }
  for (std::size_t p = 0; p < image->pixel_count(); ++p)
    if (!valid[p])
      for (int k = 0; k < 3; ++k) image->rgb[3 * p + k] = filled.data[4 * p + k];
}

std::string StitchReport::Summary() const {
  char buf[160];
  std::snprintf(buf, sizeof buf, "stitched in %.1f ms (warp %.1f, gains %.1f, fill %.1f), valid %.1f %%, gains [",
                ms_total, ms_warp, ms_gains, ms_fill, 100 * valid_fraction);
  std::string s = buf;
  std::string unused;
  for (std::size_t c = 0; c < gains.size(); ++c) {
    std::snprintf(buf, sizeof buf, "%s%.3f", c ? ", " : "", gains[c]);
    s += buf;
    if (c < camera_used.size() && !camera_used[c]) unused += (unused.empty() ? "" : ",") + std::to_string(c);
  }
  s += "]";
  if (!unused.empty()) s += ", unused cameras (missing or black): " + unused;
  return s;
}

struct Stitcher::Impl {
  Rig rig;
  StitchOptions options;
  StitchLut lut;
  double lut_ms = 0;
  ThreadPool pool;
  std::vector<LinearImage> linear;
  std::unique_ptr<GpuStitchPipeline> gpu;

  Impl(const Rig& r, const StitchOptions& o) : rig(r), options(o), pool(o.threads) {}

  void CheckImages(const std::vector<cv::Mat>& images) const {
    if (static_cast<int>(images.size()) != rig.camera_count())
      throw Error("frame set", "has " + std::to_string(images.size()) + " camera images but the rig " +
                                   rig.path.string() + " describes " + std::to_string(rig.camera_count()));
    for (int c = 0; c < rig.camera_count(); ++c) {
      const cv::Mat& m = images[static_cast<std::size_t>(c)];
      if (m.empty()) continue;
      const CameraModel& model = rig.cameras[static_cast<std::size_t>(c)].model;
      const std::string who =
          "camera " + std::to_string(c) + " (" + rig.cameras[static_cast<std::size_t>(c)].name + ")";
      if (m.cols != model.width() || m.rows != model.height())
        throw Error(who, "image is " + std::to_string(m.cols) + "x" + std::to_string(m.rows) + " but the rig " +
                             rig.path.string() + " calibrates it at " + std::to_string(model.width()) + "x" +
                             std::to_string(model.height()));
      if (m.type() != CV_8UC3)
        throw Error(who, "image is not 8-bit BGR (OpenCV type " + std::to_string(m.type()) + ")");
    }
  }

  // Linearizes every present frame; returns each frame's mean linear intensity (0 if missing).
  std::vector<double> Linearize(const std::vector<cv::Mat>& images) {
    const auto& table = SrgbTable();
    const int n = rig.camera_count();
    linear.resize(static_cast<std::size_t>(n));
    std::vector<double> means(static_cast<std::size_t>(n), 0.0);
    for (int c = 0; c < n; ++c) {
      const cv::Mat& m = images[static_cast<std::size_t>(c)];
      LinearImage& li = linear[static_cast<std::size_t>(c)];
      if (m.empty()) {
        li = {};
        continue;
      }
      li.width = m.cols;
      li.height = m.rows;
      li.rgb.resize(3 * static_cast<std::size_t>(m.cols) * m.rows);
      std::vector<double> row_sums(static_cast<std::size_t>(m.rows), 0.0);
      pool.ParallelFor(
          m.rows,
          [&](long begin, long end) {
            for (long y = begin; y < end; ++y) {
              const unsigned char* src = m.ptr<unsigned char>(static_cast<int>(y));
              float* dst = &li.rgb[3 * static_cast<std::size_t>(y) * m.cols];
              double sum = 0;
              for (int x = 0; x < m.cols; ++x, src += 3, dst += 3) {
                dst[0] = table[src[2]];
                dst[1] = table[src[1]];
                dst[2] = table[src[0]];
                sum += dst[0] + dst[1] + dst[2];
              }
              row_sums[static_cast<std::size_t>(y)] = sum;
            }
          },
          16);
      double total = 0;
      for (double s : row_sums) total += s;
      means[static_cast<std::size_t>(c)] = total / (3.0 * m.cols * m.rows);
    }
    return means;
  }

  std::vector<bool> UsableCameras(const std::vector<cv::Mat>& images, const std::vector<double>& means) const {
    const int n = rig.camera_count();
    std::vector<bool> used(static_cast<std::size_t>(n));
    for (int c = 0; c < n; ++c) {
      std::vector<double> others;
      for (int o = 0; o < n; ++o)
        if (o != c && !images[static_cast<std::size_t>(o)].empty())
          others.push_back(means[static_cast<std::size_t>(o)]);
      double median = 0;
      if (!others.empty()) {
        std::nth_element(others.begin(), others.begin() + others.size() / 2, others.end());
        median = others[others.size() / 2];
      }
      const double m = means[static_cast<std::size_t>(c)];
      used[static_cast<std::size_t>(c)] =
          !images[static_cast<std::size_t>(c)].empty() && m >= options.black_level && m >= 0.02 * median;
    }
    return used;
  }

  std::vector<double> EstimateGains(const std::vector<bool>& used) const {
    const int n = rig.camera_count();
    std::vector<std::vector<double>> counts(n, std::vector<double>(n, 0.0)), sums = counts;
    // Clipped samples say nothing about exposure (the true value is unknown): skip them.
    constexpr float kClipped = 0.98f;
    for (const std::uint32_t p : lut.gain_pixels) {
      std::array<float, kMaxStitchCameras> intensity{};
      std::array<int, kMaxStitchCameras> cams{};
      int k = 0;
      bool clipped = false;
      for (std::uint32_t e = lut.offsets[p]; e < lut.offsets[p + 1]; ++e) {
        const auto& entry = lut.entries[e];
        if (!used[entry.camera]) continue;
        float rgb[3];
        linear[entry.camera].Sample(entry.u, entry.v, rgb);
        clipped = clipped || std::max({rgb[0], rgb[1], rgb[2]}) >= kClipped;
        cams[static_cast<std::size_t>(k)] = static_cast<int>(entry.camera);
        intensity[static_cast<std::size_t>(k)] = (rgb[0] + rgb[1] + rgb[2]) / 3;
        ++k;
      }
      if (clipped || k < 2) continue;
      for (int a = 0; a < k; ++a)
        for (int b = 0; b < k; ++b) {
          if (a == b) continue;
          counts[cams[a]][cams[b]] += 1;
          sums[cams[a]][cams[b]] += intensity[static_cast<std::size_t>(a)];
        }
    }
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) sums[i][j] = counts[i][j] > 0 ? sums[i][j] / counts[i][j] : 0;
    return SolveGains(counts, sums, used, options);
  }

  void WarpCpu(const std::vector<bool>& used, const std::vector<double>& gains, StitchedFrame* out) {
    out->image = sphere::EquirectImage(lut.width, lut.height);
    out->valid.assign(lut.pixel_count(), 0);
    std::array<float, kMaxStitchCameras> g{};
    for (std::size_t c = 0; c < gains.size(); ++c) g[c] = used[c] ? static_cast<float>(gains[c]) : 0.f;
    pool.ParallelFor(
        lut.height,
        [&](long begin, long end) {
          for (std::size_t p = static_cast<std::size_t>(begin) * lut.width;
               p < static_cast<std::size_t>(end) * lut.width; ++p) {
            float acc[3] = {0, 0, 0}, wsum = 0;
            for (std::uint32_t e = lut.offsets[p]; e < lut.offsets[p + 1]; ++e) {
              const auto& entry = lut.entries[e];
              if (g[entry.camera] == 0) continue;
              float rgb[3];
              linear[entry.camera].Sample(entry.u, entry.v, rgb);
              const float w = entry.weight, wg = w * g[entry.camera];
              for (int k = 0; k < 3; ++k) acc[k] += wg * rgb[k];
              wsum += w;
            }
            if (wsum > 0) {
              float* dst = &out->image.rgb[3 * p];
              for (int k = 0; k < 3; ++k) dst[k] = acc[k] / wsum;
              out->valid[p] = 1;
            }
          }
        },
        4);
  }
};

Stitcher::Stitcher(const Rig& rig, const StitchOptions& options) : impl_(std::make_unique<Impl>(rig, options)) {
  options.Check();
  const auto t0 = Clock::now();
  impl_->lut = BuildStitchLut(rig, options);
  impl_->lut_ms = MsSince(t0);
  if (options.device == StitchDevice::kGpu) impl_->gpu = std::make_unique<GpuStitchPipeline>(rig, impl_->lut);
}

Stitcher::~Stitcher() = default;

const StitchLut& Stitcher::lut() const { return impl_->lut; }
const StitchOptions& Stitcher::options() const { return impl_->options; }
double Stitcher::lut_build_ms() const { return impl_->lut_ms; }

StitchedFrame Stitcher::Stitch(const FrameSet& set) {
  std::vector<cv::Mat> images;
  for (const auto& f : set.frames) images.push_back(f.image);
  return Stitch(images);
}

StitchedFrame Stitcher::Stitch(const std::vector<cv::Mat>& images) {
  Impl& s = *impl_;
  s.CheckImages(images);
  const auto t0 = Clock::now();
  StitchedFrame out;
  StitchReport& r = out.report;
  r.camera_mean = s.Linearize(images);
  r.camera_used = s.UsableCameras(images, r.camera_mean);
  r.ms_prepare = MsSince(t0);
  auto t = Clock::now();
  r.gains.assign(static_cast<std::size_t>(s.rig.camera_count()), 1.0);
  if (s.options.compensate_gains) r.gains = s.EstimateGains(r.camera_used);
  r.ms_gains = MsSince(t);
  t = Clock::now();
  if (s.gpu) {
    s.gpu->Run(images, r.camera_used, r.gains, s.options.fill_unseen, &out.image, &out.valid);
    r.ms_warp = MsSince(t);  // the GPU does warp and fill in one submission
  } else {
    s.WarpCpu(r.camera_used, r.gains, &out);
    r.ms_warp = MsSince(t);
    t = Clock::now();
    if (s.options.fill_unseen) FillUnseen(&out.image, out.valid, &s.pool);
    r.ms_fill = MsSince(t);
  }
  std::size_t valid = 0;
  for (auto v : out.valid) valid += v;
  r.valid_fraction = static_cast<double>(valid) / static_cast<double>(out.valid.size());
  r.ms_total = MsSince(t0);
  return out;
}

}  // namespace odvr::capture
