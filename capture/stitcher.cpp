#include "capture/stitcher.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>

#include "capture/source.h"
#include "capture/stitcher_gpu.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/srgb.h"
#include "core/timing.h"
#include "engine/image/image_io.h"
#include "engine/sphere/equirect.h"

namespace odvr::capture {
namespace {

using Clock = std::chrono::steady_clock;

// Four floats as one SIMD value (SSE on x86-64, NEON on ARM, through GCC/Clang vector
// extensions): one pixel's RGB plus a spare lane, so a bilinear tap is one load.
using V4 = float __attribute__((vector_size(16)));
struct alignas(16) Px {
  float c[4];
};
inline V4 Load(const Px* p) {
  V4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void Store(Px* p, V4 v) { std::memcpy(p, &v, sizeof v); }

// One lookup-table entry prepared for the CPU: the camera (top 5 bits) and the index of the
// top-left bilinear tap in the concatenated camera pixels (low 27 bits), the bilinear fractions
// and the feather weight. A tap clamped at the image edge (OpenCV pixel -0.5 .. 0 or W - 1 ..
// W - 0.5) gets fraction 0, so its neighbour beyond the edge is read with weight 0 and the
// sample equals the clamped one exactly, with no branch per pixel.
struct Tap {
  std::uint32_t packed;
  float au, av, weight;
};
constexpr int kTapIndexBits = 27;
constexpr std::uint32_t kTapIndexMask = (1u << kTapIndexBits) - 1;

// Bilinear sample at a tap; the GPU's stitch_warp.comp evaluates the same expression.
inline V4 SampleTap(const Px* pixels, const Tap& t, std::uint32_t stride) {
  const Px* p = pixels + (t.packed & kTapIndexMask);
  const V4 p00 = Load(p), p10 = Load(p + 1), p01 = Load(p + stride), p11 = Load(p + stride + 1);
  const V4 top = p00 + t.au * (p10 - p00);
  const V4 bottom = p01 + t.au * (p11 - p01);
  return top + t.av * (bottom - top);
}

// Size of a camera image at `level` (0 or 1): the half-resolution level rounds up, its last
// column (row) averaging the image's last column (row) with itself.
inline int LevelSize(int full, int level) { return level ? (full + 1) / 2 : full; }

// A linear sample at or above this (in any channel) is taken as clipped: its true value, and so
// what it says about exposure or alignment, is unknown.
constexpr float kClipped = 0.98f;

}  // namespace

float FeatherWeight(double u, double v, int width, int height, double margin) {
  const double tu = std::min(u + 0.5, width - 0.5 - u) / (0.5 * width * margin);
  const double tv = std::min(v + 0.5, height - 0.5 - v) / (0.5 * height * margin);
  return static_cast<float>(std::clamp(tu, 0.0, 1.0) * std::clamp(tv, 0.0, 1.0));
}

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
  if (!(feather_margin > 0 && feather_margin <= 1)) throw UsageError("feather_margin", "must be in (0, 1]");
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
              const float w = FeatherWeight(px.x(), px.y(), m.width(), m.height(), options.feather_margin);
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
  // The output's pixel pitch against each camera's at its centre (radians per pixel).
  const double output_pitch = 2 * kPi / lut.width;
  for (const auto& c : rig.cameras) {
    const CameraModel& m = c.model;
    const double pitch =
        m.type() == CameraModelType::kEquirectangular ? 2 * kPi / m.width() : 1 / std::max(m.fx(), m.fy());
    const bool half = options.prefilter == StitchOptions::Prefilter::kOn ||
                      (options.prefilter == StitchOptions::Prefilter::kAuto && output_pitch > pitch);
    lut.level.push_back(half ? 1 : 0);
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

// One pull-push pyramid level: premultiplied RGB and coverage per pixel.
struct Level {
  int width = 0, height = 0;
  std::vector<Px> data;
  void Resize(int w, int h) {
    width = w;
    height = h;
    data.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  }
  Px* row(int y) { return &data[static_cast<std::size_t>(y) * width]; }
  const Px* row(int y) const { return &data[static_cast<std::size_t>(y) * width]; }
};

// The coarse level's colour at fine pixel (x, y): bilinear, wrapping in longitude and clamped in
// latitude. shaders/stitch_push.comp evaluates the same expression.
V4 Upsample(const Level& coarse, int x, int y) {
  const float sx = (x + 0.5f) * 0.5f - 0.5f, sy = (y + 0.5f) * 0.5f - 0.5f;
  const float fx = std::floor(sx), fy = std::floor(sy);
  const float ax = sx - fx, ay = sy - fy;
  const int w = coarse.width, h = coarse.height;
  // fx >= -1 and x < 2 w: the wrap needs no integer division (per pixel, it would dominate).
  const int xi = static_cast<int>(fx);
  const int x0 = xi < 0 ? xi + w : (xi >= w ? xi - w : xi), x1 = x0 + 1 == w ? 0 : x0 + 1;
  const int y0 = std::clamp(static_cast<int>(fy), 0, h - 1), y1 = std::clamp(static_cast<int>(fy) + 1, 0, h - 1);
  const V4 c00 = Load(coarse.row(y0) + x0), c10 = Load(coarse.row(y0) + x1);
  const V4 c01 = Load(coarse.row(y1) + x0), c11 = Load(coarse.row(y1) + x1);
  const V4 top = c00 + ax * (c10 - c00);
  const V4 bottom = c01 + ax * (c11 - c01);
  return top + ay * (bottom - top);
}

// Coarse row y of the pull from `fine`: each coarse pixel averages its (up to) 2x2 children;
// columns wrap around the seam. `fine_at(x, y)` gives a fine pixel's premultiplied colour and
// coverage. shaders/stitch_pull.comp sums in the same order.
template <typename FineAt>
void PullRow(int fine_width, int fine_height, const FineAt& fine_at, Level* coarse, int y) {
  Px* out = coarse->row(y);
  for (int x = 0; x < coarse->width; ++x) {
    V4 sum = {0, 0, 0, 0};
    int n = 0;
    for (int dy = 0; dy < 2; ++dy) {
      const int fy = 2 * y + dy;
      if (fy >= fine_height) continue;
      for (int dx = 0; dx < 2; ++dx) {
        const int fx = 2 * x + dx;
        sum += fine_at(fx >= fine_width ? fx - fine_width : fx, fy);
        ++n;
      }
    }
    Store(out + x, sum / static_cast<float>(n));
  }
}

// Row y of level 1 of the pyramid, pulled straight from the image and its validity mask (level
// 0 itself is never stored: its premultiplied value is (rgb, 1) where valid and 0 elsewhere).
// The same sums as PullRow, without its per-pixel wrap and row checks where none is needed.
void PullFromImage(const sphere::EquirectImage& image, const std::uint8_t* valid, Level* level1, int y) {
  const int w = image.width;
  const auto at = [&](int x, int fy) -> V4 {
    const std::size_t p = static_cast<std::size_t>(fy) * w + x;
    if (!valid[p]) return V4{0, 0, 0, 0};
    const float* c = &image.rgb[3 * p];
    return V4{c[0], c[1], c[2], 1.0f};
  };
  if (2 * y + 1 >= image.height || w % 2) {
    PullRow(w, image.height, at, level1, y);
    return;
  }
  Px* out = level1->row(y);
  for (int x = 0; x < level1->width; ++x)
    Store(out + x,
          (((at(2 * x, 2 * y) + at(2 * x + 1, 2 * y)) + at(2 * x, 2 * y + 1)) + at(2 * x + 1, 2 * y + 1)) / 4.0f);
}

void ForRows(ThreadPool* pool, int rows, long min_chunk, const std::function<void(long, long)>& body) {
  if (pool) {
    pool->ParallelFor(rows, body, min_chunk);
  } else {
    body(0, rows);
  }
}

// Buffers of the pull-push fill, kept between frames (no allocation per frame).
struct Pyramid {
  std::vector<Level> levels;  // levels[0] is pyramid level 1 (half the image), up to 1x1
  std::vector<Level> filled;  // the pushed colour of each of those levels

  void Resize(int width, int height) {
    std::vector<std::array<int, 2>> sizes;
    int w = width, h = height;
    do {
      w = (w + 1) / 2;
      h = (h + 1) / 2;
      sizes.push_back({w, h});
    } while (w > 1 || h > 1);
    levels.resize(sizes.size());
    filled.resize(sizes.size());
    for (std::size_t l = 0; l < sizes.size(); ++l) {
      levels[l].Resize(sizes[l][0], sizes[l][1]);
      filled[l].Resize(sizes[l][0], sizes[l][1]);
    }
  }

  // With levels[0] pulled from the image, pulls the coarser levels, pushes back down to level 1
  // and fills the image's invalid pixels from it (Gortler's push with alpha = coverage; valid
  // pixels keep their values exactly, and an invalid one has no content of its own, so its
  // value is the upsampled level 1 alone).
  void Fill(sphere::EquirectImage* image, const std::uint8_t* valid, ThreadPool* pool) {
    for (std::size_t l = 1; l < levels.size(); ++l) {
      const Level& fine = levels[l - 1];
      ForRows(pool, levels[l].height, 16, [&](long begin, long end) {
        for (long y = begin; y < end; ++y)
          PullRow(
              fine.width, fine.height, [&](int x, int fy) { return Load(fine.row(fy) + x); }, &levels[l],
              static_cast<int>(y));
      });
    }
    // Top (1x1): un-premultiplied.
    {
      const V4 t = Load(levels.back().row(0));
      Store(filled.back().row(0), t[3] > 0 ? t / t[3] : V4{0, 0, 0, 0});
    }
    for (std::size_t l = levels.size() - 1; l-- > 0;) {
      const Level& own = levels[l];
      const Level& coarse = filled[l + 1];
      Level& next = filled[l];
      ForRows(pool, own.height, 8, [&](long begin, long end) {
        for (long y = begin; y < end; ++y) {
          const Px* o = own.row(static_cast<int>(y));
          Px* dst = next.row(static_cast<int>(y));
          for (int x = 0; x < own.width; ++x) {
            const V4 ov = Load(o + x);
            // A fully covered pixel keeps its own colour ((1 − 1)·up adds nothing).
            Store(dst + x, ov[3] >= 1 ? ov : ov + (1 - ov[3]) * Upsample(coarse, x, static_cast<int>(y)));
          }
        }
      });
    }
    const Level& level1 = filled[0];
    const int w = image->width;
    ForRows(pool, image->height, 8, [&](long begin, long end) {
      for (long y = begin; y < end; ++y)
        for (int x = 0; x < w; ++x) {
          const std::size_t p = static_cast<std::size_t>(y) * w + x;
          if (valid[p]) continue;
          const V4 up = Upsample(level1, x, static_cast<int>(y));
          for (int k = 0; k < 3; ++k) image->rgb[3 * p + static_cast<std::size_t>(k)] = up[k];
        }
    });
  }
};

}  // namespace

void FillUnseen(sphere::EquirectImage* image, const std::vector<std::uint8_t>& valid, ThreadPool* pool) {
  Pyramid pyramid;
  pyramid.Resize(image->width, image->height);
  ForRows(pool, pyramid.levels[0].height, 8, [&](long begin, long end) {
    for (long y = begin; y < end; ++y) PullFromImage(*image, valid.data(), &pyramid.levels[0], static_cast<int>(y));
  });
  pyramid.Fill(image, valid.data(), pool);
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
    if (c < camera_used.size() && !camera_used[c]) {
      // Appended in two steps: GCC 12 at -O3 takes `"," + std::to_string(c)` for an overlapping
      // memcpy (-Wrestrict, a false positive) and a Release build with ODVR_WERROR fails.
      if (!unused.empty()) unused += ',';
      unused += std::to_string(c);
    }
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
  std::unique_ptr<GpuStitchPipeline> gpu;
  // CPU path: the lookup table as taps into `pixels`, every camera's linear (and, where the
  // table says so, smoothed) RGB one after the other from first_pixel[c], rows of width[c].
  std::vector<Tap> taps;
  std::vector<std::size_t> first_pixel;
  std::vector<std::uint32_t> stride;
  std::vector<Px> pixels;
  // Gain samples: the pixels of lut.gain_pixels[i] are samples [gain_first[i], gain_first[i + 1])
  // of gain_camera / gain_value. Each is the nearest pixel of its camera's level, read while the
  // linearization has that row in cache: level row r (cameras' rows one after the other from
  // level_first_row[c]) holds items [gain_row_first[r], gain_row_first[r + 1]) of gain_items.
  struct GainItem {
    std::uint32_t x, sample;
  };
  std::vector<std::uint32_t> gain_first, gain_camera, gain_row_first, level_first_row;
  std::vector<GainItem> gain_items;
  std::vector<float> gain_value;  // per frame: mean of R, G, B; negative where clipped
  Pyramid pyramid;

  Impl(const Rig& r, const StitchOptions& o) : rig(r), options(o), pool(o.threads) {}

  void PrepareCpu() {
    std::size_t total = 0;
    std::uint32_t widest = 0;
    for (int c = 0; c < rig.camera_count(); ++c) {
      const CameraModel& m = rig.cameras[static_cast<std::size_t>(c)].model;
      const int level = lut.level[static_cast<std::size_t>(c)];
      first_pixel.push_back(total);
      stride.push_back(static_cast<std::uint32_t>(LevelSize(m.width(), level)));
      widest = std::max(widest, stride.back());
      total += static_cast<std::size_t>(stride.back()) * static_cast<std::size_t>(LevelSize(m.height(), level));
    }
    // The bottom-right tap of the last pixel reaches one row and one pixel beyond it.
    const std::size_t padded = total + widest + 1;
    if (padded > kTapIndexMask)
      throw Error(rig.path.string(), "the cameras have " + std::to_string(total) +
                                         " pixels together; the CPU stitcher indexes 2^27 at most");
    pixels.assign(padded, Px{{0, 0, 0, 0}});
    taps.resize(lut.entries.size());
    for (std::size_t e = 0; e < lut.entries.size(); ++e) {
      const StitchLut::Entry& in = lut.entries[e];
      const CameraModel& m = rig.cameras[in.camera].model;
      const int level = lut.level[in.camera];
      const int w = LevelSize(m.width(), level), h = LevelSize(m.height(), level);
      // stitch_warp.comp maps to the level with the same (exact) float operations.
      const float u = level ? (in.u - 0.5f) * 0.5f : in.u, v = level ? (in.v - 0.5f) * 0.5f : in.v;
      const float fu = std::floor(u), fv = std::floor(v);
      float au = u - fu, av = v - fv;
      int x0 = static_cast<int>(fu), y0 = static_cast<int>(fv);
      if (x0 < 0 || x0 >= w - 1) {
        x0 = std::clamp(x0, 0, w - 1);
        au = 0;
      }
      if (y0 < 0 || y0 >= h - 1) {
        y0 = std::clamp(y0, 0, h - 1);
        av = 0;
      }
      const std::size_t index = first_pixel[in.camera] + static_cast<std::size_t>(y0) * w + x0;
      taps[e] = {static_cast<std::uint32_t>(index) | (in.camera << kTapIndexBits), au, av, in.weight};
    }
    PrepareGainSamples();
    if (options.fill_unseen && options.device == StitchDevice::kCpu) pyramid.Resize(lut.width, lut.height);
  }

  void PrepareGainSamples() {
    const int n = rig.camera_count();
    level_first_row.assign(static_cast<std::size_t>(n) + 1, 0);
    for (int c = 0; c < n; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      level_first_row[cu + 1] =
          level_first_row[cu] + static_cast<std::uint32_t>(LevelSize(rig.cameras[cu].model.height(), lut.level[cu]));
    }
    std::vector<std::vector<GainItem>> rows(level_first_row.back());
    gain_first.assign(1, 0);
    gain_camera.clear();
    for (const std::uint32_t p : lut.gain_pixels) {
      for (std::uint32_t e = lut.offsets[p]; e < lut.offsets[p + 1]; ++e) {
        const StitchLut::Entry& in = lut.entries[e];
        const int level = lut.level[in.camera];
        const CameraModel& m = rig.cameras[in.camera].model;
        const float u = level ? (in.u - 0.5f) * 0.5f : in.u, v = level ? (in.v - 0.5f) * 0.5f : in.v;
        const int x = std::clamp(static_cast<int>(std::lround(u)), 0, LevelSize(m.width(), level) - 1);
        const int y = std::clamp(static_cast<int>(std::lround(v)), 0, LevelSize(m.height(), level) - 1);
        rows[level_first_row[in.camera] + static_cast<std::uint32_t>(y)].push_back(
            {static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(gain_camera.size())});
        gain_camera.push_back(in.camera);
      }
      gain_first.push_back(static_cast<std::uint32_t>(gain_camera.size()));
    }
    gain_row_first.assign(1, 0);
    gain_items.clear();
    for (auto& r : rows) {
      std::sort(r.begin(), r.end(), [](const GainItem& a, const GainItem& b) { return a.x < b.x; });
      gain_items.insert(gain_items.end(), r.begin(), r.end());
      gain_row_first.push_back(static_cast<std::uint32_t>(gain_items.size()));
    }
    gain_value.assign(gain_camera.size(), 0.f);
  }

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

  // Linearizes every present frame into `pixels`, at the level lut.level gives each camera, and
  // reads the gain samples on the way. Returns each frame's mean linear intensity (0 if missing).
  std::vector<double> Linearize(const std::vector<cv::Mat>& images) {
    const auto& table = Srgb8ToLinearTable();
    const int n = rig.camera_count();
    // Clipped samples say nothing about exposure (the true value is unknown): marked negative.
    // All cameras' level rows as one index range, so both threads share every camera's work.
    const auto& first_row = level_first_row;
    std::vector<double> row_sums(first_row.back(), 0.0);
    pool.ParallelFor(
        first_row.back(),
        [&](long begin, long end) {
          for (long r = begin; r < end; ++r) {
            const auto cu = static_cast<std::size_t>(
                std::upper_bound(first_row.begin(), first_row.end(), static_cast<std::uint32_t>(r)) -
                first_row.begin() - 1);
            const cv::Mat& m = images[cu];
            if (m.empty()) continue;
            const int y = static_cast<int>(r - first_row[cu]);
            const int w = m.cols;
            Px* out = &pixels[first_pixel[cu] + static_cast<std::size_t>(y) * stride[cu]];
            const auto lin = [&](const unsigned char* bgr) {
              return V4{table[bgr[2]], table[bgr[1]], table[bgr[0]], 0.f};
            };
            V4 sum = {0, 0, 0, 0};
            if (!lut.level[cu]) {
              const unsigned char* src = m.ptr<unsigned char>(y);
              for (int x = 0; x < w; ++x, src += 3) {
                const V4 v = lin(src);
                Store(out + x, v);
                sum += v;
              }
            } else {
              // 2x2 box: ((p00 + p10) + p01) + p11, as stitch_linearize.comp sums it. An odd
              // last column or row averages the image's last one with itself, and counts once
              // in the mean.
              const bool has_bottom = 2 * y + 1 < m.rows;
              const unsigned char* top = m.ptr<unsigned char>(2 * y);
              const unsigned char* bottom = m.ptr<unsigned char>(has_bottom ? 2 * y + 1 : 2 * y);
              const int pairs = w / 2;
              for (int x = 0; x < pairs; ++x, top += 6, bottom += 6) {
                const V4 a = lin(top), b = lin(top + 3), c = lin(bottom), d = lin(bottom + 3);
                const V4 box = a + b + c + d;
                Store(out + x, box * 0.25f);
                sum += has_bottom ? box : a + b;
              }
              if (w % 2) {
                const V4 a = lin(top), c = lin(bottom);
                Store(out + pairs, (a + a + c + c) * 0.25f);
                sum += has_bottom ? a + c : a;
              }
            }
            row_sums[static_cast<std::size_t>(r)] = static_cast<double>(sum[0]) + sum[1] + sum[2];
            for (std::uint32_t i = gain_row_first[static_cast<std::size_t>(r)];
                 i < gain_row_first[static_cast<std::size_t>(r) + 1]; ++i) {
              const V4 v = Load(out + gain_items[i].x);
              const bool clipped = std::max({v[0], v[1], v[2]}) >= kClipped;
              gain_value[gain_items[i].sample] = clipped ? -1.f : (v[0] + v[1] + v[2]) / 3;
            }
          }
        },
        8);
    std::vector<double> means(static_cast<std::size_t>(n), 0.0);
    for (int c = 0; c < n; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      const cv::Mat& m = images[cu];
      if (m.empty()) continue;
      double total = 0;
      for (std::uint32_t r = first_row[cu]; r < first_row[cu + 1]; ++r) total += row_sums[r];
      means[cu] = total / (3.0 * m.cols * m.rows);
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
    std::array<bool, kMaxStitchCameras> use{};
    for (int c = 0; c < n; ++c) use[static_cast<std::size_t>(c)] = used[static_cast<std::size_t>(c)];
    std::vector<double> count(static_cast<std::size_t>(n) * n, 0.0), sum = count;
    for (std::size_t i = 0; i + 1 < gain_first.size(); ++i) {
      std::array<float, kMaxStitchCameras> intensity{};
      std::array<std::uint32_t, kMaxStitchCameras> cams{};
      int k = 0;
      bool clipped = false;
      for (std::uint32_t j = gain_first[i]; j < gain_first[i + 1]; ++j) {
        if (!use[gain_camera[j]]) continue;
        clipped = clipped || gain_value[j] < 0;
        cams[static_cast<std::size_t>(k)] = gain_camera[j];
        intensity[static_cast<std::size_t>(k)] = gain_value[j];
        ++k;
      }
      if (clipped || k < 2) continue;
      for (int a = 0; a < k; ++a)
        for (int b = 0; b < k; ++b) {
          if (a == b) continue;
          const std::size_t ab = static_cast<std::size_t>(cams[a]) * n + cams[b];
          count[ab] += 1;
          sum[ab] += intensity[static_cast<std::size_t>(a)];
        }
    }
    std::vector<std::vector<double>> counts(n, std::vector<double>(n, 0.0)), means = counts;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const std::size_t ij = static_cast<std::size_t>(i) * n + j;
        counts[i][j] = count[ij];
        means[i][j] = count[ij] > 0 ? sum[ij] / count[ij] : 0;
      }
    return SolveGains(counts, means, used, options);
  }

  // The seams' disagreement (ChooseSceneDistance): over output pixels seen by two or more used
  // cameras, none of them clipped, the sums of cos(latitude) times the feathered mean of each
  // gain-corrected sample's squared difference from the blend (mean over R, G, B), of
  // cos(latitude), and the pixel count.
  struct SeamSums {
    double disagreement = 0, weight = 0;
    long pixels = 0;
  };
  SeamSums SeamDisagreement(const std::vector<bool>& used, const std::vector<double>& gains) {
    std::array<float, kMaxStitchCameras> g{};
    for (std::size_t c = 0; c < gains.size(); ++c) g[c] = used[c] ? static_cast<float>(gains[c]) : 0.f;
    const int w = lut.width, h = lut.height;
    std::vector<SeamSums> rows(static_cast<std::size_t>(h));
    const Px* px = pixels.data();
    pool.ParallelFor(
        h,
        [&](long begin, long end) {
          for (long row = begin; row < end; ++row) {
            const double cos_lat = std::cos(kPi * ((static_cast<double>(row) + 0.5) / h - 0.5));
            SeamSums& out = rows[static_cast<std::size_t>(row)];
            for (int col = 0; col < w; ++col) {
              const std::size_t p = static_cast<std::size_t>(row) * w + col;
              // Two passes (the blend, then the differences from it), so that identical samples
              // score exactly 0 rather than the rounding of a difference of squares.
              std::array<V4, kMaxStitchCameras> v;
              std::array<float, kMaxStitchCameras> wt;
              V4 acc = {0, 0, 0, 0};
              float wsum = 0;
              int seen = 0;
              bool clipped = false;
              for (std::uint32_t e = lut.offsets[p]; e < lut.offsets[p + 1] && !clipped; ++e) {
                const Tap& t = taps[e];
                const std::uint32_t camera = t.packed >> kTapIndexBits;
                if (g[camera] == 0) continue;
                const V4 raw = SampleTap(px, t, stride[camera]);
                clipped = std::max({raw[0], raw[1], raw[2]}) >= kClipped;
                v[static_cast<std::size_t>(seen)] = g[camera] * raw;
                wt[static_cast<std::size_t>(seen)] = t.weight;
                acc += t.weight * v[static_cast<std::size_t>(seen)];
                wsum += t.weight;
                ++seen;
              }
              if (clipped || seen < 2) continue;
              const V4 mean = acc / wsum;
              V4 var = {0, 0, 0, 0};
              for (int k = 0; k < seen; ++k) {
                const V4 d = v[static_cast<std::size_t>(k)] - mean;
                var += wt[static_cast<std::size_t>(k)] * d * d;
              }
              var /= wsum;
              out.disagreement += cos_lat * (static_cast<double>(var[0]) + var[1] + var[2]) / 3;
              out.weight += cos_lat;
              ++out.pixels;
            }
          }
        },
        4);
    SeamSums total;
    for (const SeamSums& r : rows) {
      total.disagreement += r.disagreement;
      total.weight += r.weight;
      total.pixels += r.pixels;
    }
    return total;
  }

  // Blends every output pixel; with the fill on, pulls level 1 of its pyramid on the way (two
  // output rows at a time, while they are in cache). Returns the number of valid pixels.
  std::size_t WarpCpu(const std::vector<bool>& used, const std::vector<double>& gains, StitchedFrame* out) {
    if (out->image.width != lut.width || out->image.height != lut.height ||
        out->image.rgb.size() != 3 * lut.pixel_count())
      out->image = sphere::EquirectImage(lut.width, lut.height);
    out->valid.resize(lut.pixel_count());
    std::array<float, kMaxStitchCameras> g{};
    for (std::size_t c = 0; c < gains.size(); ++c) g[c] = used[c] ? static_cast<float>(gains[c]) : 0.f;
    const int w = lut.width, h = lut.height, pairs = (h + 1) / 2;
    std::vector<std::uint32_t> valid_per_pair(static_cast<std::size_t>(pairs), 0);
    float* rgb = out->image.rgb.data();
    std::uint8_t* valid = out->valid.data();
    const Px* px = pixels.data();
    const bool fill = options.fill_unseen;
    constexpr std::size_t kPrefetchTaps = 32;
    const std::size_t last_tap = taps.empty() ? 0 : taps.size() - 1;
    pool.ParallelFor(
        pairs,
        [&](long begin, long end) {
          for (long pair = begin; pair < end; ++pair) {
            std::uint32_t count = 0;
            const std::size_t p_begin = static_cast<std::size_t>(2 * pair) * w;
            const std::size_t p_end = static_cast<std::size_t>(std::min<long>(2 * pair + 2, h)) * w;
            for (std::size_t p = p_begin; p < p_end; ++p) {
              V4 acc = {0, 0, 0, 0};
              float wsum = 0;
              for (std::uint32_t e = lut.offsets[p]; e < lut.offsets[p + 1]; ++e) {
                // The taps wander along curves through the camera images, which hardware
                // prefetchers do not follow: fetch the rows of a tap a little ahead.
                {
                  const Tap& ahead = taps[std::min<std::size_t>(e + kPrefetchTaps, last_tap)];
                  const Px* q = px + (ahead.packed & kTapIndexMask);
                  __builtin_prefetch(q);
                  __builtin_prefetch(q + stride[ahead.packed >> kTapIndexBits]);
                }
                const Tap& t = taps[e];
                const std::uint32_t camera = t.packed >> kTapIndexBits;
                const float gain = g[camera];
                if (gain == 0) continue;
                acc += (t.weight * gain) * SampleTap(px, t, stride[camera]);
                wsum += t.weight;
              }
              // Unseen pixels are written too (black), as the buffer may hold an earlier frame.
              const V4 v = wsum > 0 ? acc / wsum : V4{0, 0, 0, 0};
              float* dst = rgb + 3 * p;
              dst[0] = v[0];
              dst[1] = v[1];
              dst[2] = v[2];
              valid[p] = wsum > 0;
              count += wsum > 0;
            }
            valid_per_pair[static_cast<std::size_t>(pair)] = count;
            if (fill) PullFromImage(out->image, valid, &pyramid.levels[0], static_cast<int>(pair));
          }
        },
        4);
    std::size_t total = 0;
    for (const auto v : valid_per_pair) total += v;
    return total;
  }
};

Stitcher::Stitcher(const Rig& rig, const StitchOptions& options) : impl_(std::make_unique<Impl>(rig, options)) {
  options.Check();
  const auto t0 = Clock::now();
  impl_->lut = BuildStitchLut(rig, options);
  impl_->PrepareCpu();
  if (options.device == StitchDevice::kGpu) impl_->gpu = std::make_unique<GpuStitchPipeline>(rig, impl_->lut);
  impl_->lut_ms = MsSince(t0);
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
  StitchedFrame out;
  Stitch(images, &out);
  return out;
}

void Stitcher::Stitch(const std::vector<cv::Mat>& images, StitchedFrame* frame) {
  Impl& s = *impl_;
  s.CheckImages(images);
  const auto t0 = Clock::now();
  StitchedFrame& out = *frame;
  StitchReport& r = out.report;
  r = {};
  const int n = s.rig.camera_count();
  r.gains.assign(static_cast<std::size_t>(n), 1.0);
  std::size_t valid = 0;
  // Both devices take the means (black frames) and the gains from the CPU's linear frames.
  r.camera_mean = s.Linearize(images);
  r.camera_used = s.UsableCameras(images, r.camera_mean);
  r.ms_prepare = MsSince(t0);
  auto t = Clock::now();
  if (s.options.compensate_gains) r.gains = s.EstimateGains(r.camera_used);
  r.ms_gains = MsSince(t);
  t = Clock::now();
  if (s.gpu) {
    s.gpu->Run(images, r.camera_used, r.gains, s.options.fill_unseen, &out.image, &out.valid, &r);
    r.ms_warp = MsSince(t);  // the GPU does warp and fill in one submission
    for (auto v : out.valid) valid += v;
  } else {
    valid = s.WarpCpu(r.camera_used, r.gains, &out);
    r.ms_warp = MsSince(t);
    t = Clock::now();
    if (s.options.fill_unseen && valid < out.valid.size()) s.pyramid.Fill(&out.image, out.valid.data(), &s.pool);
    r.ms_fill = MsSince(t);
  }
  r.valid_fraction = static_cast<double>(valid) / static_cast<double>(out.valid.size());
  r.ms_total = MsSince(t0);
}

void SceneDistanceSearch::Check() const {
  if (candidates_m.empty()) throw UsageError("candidates_m", "needs at least one candidate distance");
  for (const double d : candidates_m)
    if (!(d >= 0) || !std::isfinite(d)) throw UsageError("candidates_m", "must be 0 (infinity) or positive distances");
  if (width < 8 || width % 2) throw UsageError("width", "must be even and at least 8");
  if (!(min_improvement >= 0 && min_improvement < 1)) throw UsageError("min_improvement", "must be in [0, 1)");
  if (min_samples < 1) throw UsageError("min_samples", "must be at least 1");
}

namespace {

// A seam RMS (linear) below which the cameras agree to within float rounding: far below 8-bit
// quantization (a step of 1 / 255 in sRGB is 3e-4 linear at black).
constexpr double kNoDisagreement = 1e-5;

std::string DistanceName(double d) {
  if (d <= 0) return "inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g m", d);
  return buf;
}

}  // namespace

std::string SceneDistanceChoice::Summary() const {
  std::string s =
      "scene distance " + (distance_m > 0 ? DistanceName(distance_m) : std::string("infinity")) + " (seam RMS";
  char buf[64];
  for (std::size_t i = 0; i < candidates_m.size() && i < scores.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s %s %.5f", i ? "," : ":", DistanceName(candidates_m[i]).c_str(), scores[i]);
    s += buf;
  }
  std::snprintf(buf, sizeof buf, "; %d frame set%s, %.0f ms)", frame_sets, frame_sets == 1 ? "" : "s", ms);
  s += buf;
  if (!reason.empty()) s += "; infinity kept: " + reason;
  return s;
}

SceneDistanceChoice ChooseSceneDistance(const Rig& rig, const std::vector<std::vector<cv::Mat>>& frame_sets,
                                        const StitchOptions& options, const SceneDistanceSearch& search) {
  search.Check();
  const auto t0 = Clock::now();
  SceneDistanceChoice out;
  out.candidates_m = search.candidates_m;
  if (std::find(out.candidates_m.begin(), out.candidates_m.end(), 0.0) == out.candidates_m.end())
    out.candidates_m.push_back(0);
  out.frame_sets = static_cast<int>(frame_sets.size());
  StitchOptions o = options;
  o.width = search.width;
  o.height = search.width / 2;
  o.device = StitchDevice::kCpu;
  o.fill_unseen = false;
  for (const double d : out.candidates_m) {
    o.scene_distance_m = d;
    Stitcher stitcher(rig, o);
    Stitcher::Impl& s = *stitcher.impl_;
    double score_sum = 0;
    int scored = 0;
    long pixels = 0;
    for (const auto& images : frame_sets) {
      s.CheckImages(images);
      const std::vector<double> means = s.Linearize(images);
      const std::vector<bool> used = s.UsableCameras(images, means);
      const std::vector<double> gains =
          o.compensate_gains ? s.EstimateGains(used) : std::vector<double>(used.size(), 1.0);
      const auto sums = s.SeamDisagreement(used, gains);
      pixels += sums.pixels;
      if (sums.weight > 0) {
        score_sum += std::sqrt(sums.disagreement / sums.weight);
        ++scored;
      }
    }
    out.scores.push_back(scored ? score_sum / scored : std::nan(""));
    out.samples.push_back(pixels);
  }
  const std::size_t at_infinity = static_cast<std::size_t>(
      std::find(out.candidates_m.begin(), out.candidates_m.end(), 0.0) - out.candidates_m.begin());
  const double infinity_score = out.scores[at_infinity];
  std::size_t best = at_infinity;
  for (std::size_t i = 0; i < out.candidates_m.size(); ++i)
    if (out.samples[i] >= search.min_samples && out.scores[i] < out.scores[best]) best = i;
  char buf[200];
  if (frame_sets.empty()) {
    out.reason = "no frame set to score";
  } else if (out.samples[at_infinity] < search.min_samples) {
    std::snprintf(buf, sizeof buf, "the overlaps hold %ld usable pixels, fewer than the %ld needed to compare",
                  out.samples[at_infinity], search.min_samples);
    out.reason = buf;
  } else if (!(infinity_score > kNoDisagreement)) {
    out.reason = "the overlaps agree at infinity to within rounding (no texture to align)";
  } else if (1 - out.scores[best] / infinity_score < search.min_improvement) {
    std::snprintf(buf, sizeof buf,
                  "no distance lowers the seams' disagreement by %.0f %% (best %s: %.1f %%): a textureless or "
                  "distant scene",
                  100 * search.min_improvement, DistanceName(out.candidates_m[best]).c_str(),
                  100 * (1 - out.scores[best] / infinity_score));
    out.reason = buf;
  } else {
    out.distance_m = out.candidates_m[best];
  }
  out.ms = MsSince(t0);
  return out;
}

std::optional<SceneDistanceChoice> ChooseSceneDistanceForRecording(const Rig& rig, Source* source, long first,
                                                                   long frames, const StitchOptions& options, int sets,
                                                                   const SceneDistanceSearch& search) {
  if (source->live() || sets < 1) return std::nullopt;
  long span = frames > 0 ? frames : std::max(1L, source->frame_count() - first);
  if (source->frame_count() > 0) span = std::clamp(span, 1L, std::max(1L, source->frame_count() - first));
  std::vector<std::vector<cv::Mat>> images;
  long last = -1;
  for (int k = 0; k < sets; ++k) {
    const long index = first + (sets > 1 ? k * (span - 1) / (sets - 1) : 0);
    if (index == last) continue;
    last = index;
    if (!source->Seek(index)) {
      if (images.empty()) return std::nullopt;
      break;
    }
    auto set = source->Next();
    if (!set) break;
    std::vector<cv::Mat>& one = images.emplace_back();
    for (const auto& f : set->frames) one.push_back(f.image);
  }
  source->Seek(first);
  return ChooseSceneDistance(rig, images, options, search);
}

}  // namespace odvr::capture
