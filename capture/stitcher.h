#pragma once
// Rig frames -> one equirectangular frame (seed §5.3.1, DESIGN.md §6), in linear float RGB
// following engine/sphere/equirect.h, with the output in the rig frame mapped to odvr's Y-up
// frame (rig x forward, y left, z up -> (x, z, -y)).
//
// Per output pixel: its bearing, each camera's pixel through the rig's camera models (a lookup
// table built once per rig and output size), bilinear samples of the linearized 8-bit sRGB
// images (at half resolution, 2x2 box averages, where the output samples a camera more coarsely
// than its own pixels, as a minifying resampler must), feathered blending (a camera's weight rises
// from 0 at its image edge to 1 within a margin, so overlaps average both cameras evenly), one
// gain per camera estimated from the overlaps (least squares on overlap means, as OpenCV's
// GainCompensator does), and directions no camera sees (zenith, nadir) marked invalid and filled
// by pull-push interpolation from the valid border, so the lighting built from the frame is not
// darkened by black holes.
//
// Stated behaviour for bad input:
//  * a frame set with a different number of cameras than the rig, or an image whose size is not
//    the rig's for that camera: odvr::Error naming the camera and both sizes;
//  * a missing (empty) or black frame (mean linear intensity below black_level, or below 2 % of
//    the median of the other cameras): the camera is left out of blending and of the gain
//    estimate (its gain stays 1 and is never solved from a zero mean); the other cameras still
//    stitch, and the directions only it saw become invalid and are filled.
#include <chrono>
#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame.h"
#include "capture/rig.h"
#include "core/parallel.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::capture {

enum class StitchDevice { kCpu, kGpu };

// Cameras per rig the stitcher takes (the GPU path passes per-camera gains as a uniform array
// and the cameras in use as a 32-bit mask).
inline constexpr int kMaxStitchCameras = 32;

struct StitchOptions {
  int width = 2048, height = 1024;  // output equirect size
  StitchDevice device = StitchDevice::kCpu;
  // Distance at which the cameras' rays are made to meet (metres). 0 = infinity: pure bearings,
  // right for the sky and far facades; a finite value trades near for far parallax.
  // ChooseSceneDistance picks one from the frames (`odvr stitch` does so by default).
  double scene_distance_m = 0;
  bool compensate_gains = true;
  bool fill_unseen = true;
  // Gain least squares (OpenCV GainCompensator's terms): sigma of the overlap mean difference,
  // relative to the mean overlap intensity (OpenCV: 10 grey levels at mid-grey), and of the prior
  // pulling each gain to 1. The prior only fixes the common scale and tames poorly observed
  // cameras; a looser one than OpenCV's 0.1 lets ±30 % exposure differences be recovered.
  double gain_sigma_n = 10.0 / 128.0;
  double gain_sigma_g = 0.5;
  double min_gain = 0.25, max_gain = 4.0;
  // Overlap means sample every gain_sample_step-th output pixel in each direction.
  int gain_sample_step = 4;
  // A camera's blend weight rises linearly from 0 at its image edge to 1 over this fraction of
  // its half-width (and half-height), and is 1 inside: overlaps then average the cameras evenly,
  // which averages away more of their noise than a tent across the whole image (1 = that tent).
  // 0.1 loses nothing measurable against an unfeathered average on street_a's ground truth while
  // still fading each camera out before its edge.
  double feather_margin = 0.1;
  // Sample a camera from its half-resolution level (2x2 box averages, a mipmap's level 1)
  // rather than its own pixels. kAuto: for the cameras the output samples more coarsely than
  // their own pixels (output pitch 2 pi / width above the camera's central pitch 1 / f), where
  // bilinear sampling of the full image would alias its noise and detail into the frame (the
  // level is chosen so the output never minifies: a little blur rather than aliasing).
  enum class Prefilter { kAuto, kOff, kOn };
  Prefilter prefilter = Prefilter::kAuto;
  double black_level = 1e-3;  // mean linear intensity below which a frame counts as black
  int threads = 0;            // CPU path: 0 = hardware concurrency

  // Throws odvr::UsageError naming the bad field.
  void Check() const;
};

// The per-rig, per-size table: for output pixel p, entries [offsets[p], offsets[p + 1]) give the
// cameras that see its bearing, where (OpenCV pixel coordinates of the full image), and the
// feather weight; level[c] says which level camera c is sampled from (0 = its pixels, 1 = its
// half-resolution 2x2 box average, where full-image coordinate u is (u - 0.5) / 2).
struct StitchLut {
  struct Entry {
    float u, v, weight;
    std::uint32_t camera;
  };
  int width = 0, height = 0, cameras = 0;
  std::vector<std::uint32_t> offsets;  // width * height + 1
  std::vector<Entry> entries;
  std::vector<std::uint32_t> gain_pixels;  // subsampled output pixels seen by two or more cameras
  std::vector<std::uint8_t> level;         // per camera: 0 = full resolution, 1 = half

  std::size_t pixel_count() const { return static_cast<std::size_t>(width) * static_cast<std::size_t>(height); }
};

StitchLut BuildStitchLut(const Rig& rig, const StitchOptions& options);

// Least squares on overlap means (Brown & Lowe; OpenCV detail::GainCompensator):
//   min_g  sum_{i != j} N_ij [ (g_i I_ij - g_j I_ji)^2 / sigma_n^2 + (1 - g_i)^2 / sigma_g^2 ]
// where N_ij counts the samples seen by both i and j and I_ij is camera i's mean there.
// Cameras with usable[i] false get gain 1 and take no part. Results are clamped to
// [min_gain, max_gain].
std::vector<double> SolveGains(const std::vector<std::vector<double>>& counts,
                               const std::vector<std::vector<double>>& means, const std::vector<bool>& usable,
                               const StitchOptions& options);

// The feather weight of pixel (u, v) (OpenCV coordinates) of a width x height image: the product
// of a ramp in each direction, 0 on the image's outer edge, 1 from `margin` of the half-size in.
float FeatherWeight(double u, double v, int width, int height, double margin);

// Fills pixels with valid[p] == 0 by pull-push (Gortler et al. 1996): average down a pyramid
// (premultiplied by coverage, wrapping around the seam), then blend each level's own content
// with the upsampled coarser level where its coverage is incomplete. Valid pixels keep their
// values exactly. `pool` (optional) spreads the rows of each level over threads.
void FillUnseen(sphere::EquirectImage* image, const std::vector<std::uint8_t>& valid, ThreadPool* pool = nullptr);

struct StitchReport {
  std::vector<double> gains;        // applied per camera (1 for unused ones)
  std::vector<bool> camera_used;    // false: missing or black frame
  std::vector<double> camera_mean;  // mean linear intensity of each input frame
  double valid_fraction = 0;        // of output pixels (by count) seen by a used camera
  double ms_prepare = 0, ms_gains = 0, ms_warp = 0, ms_fill = 0, ms_total = 0;
  // The GPU path's ms_warp in parts (0 on the CPU): the frames' upload (wall clock), the compute
  // passes (the GPU's own clock, GL timestamps) and the read-back with its conversion to the
  // frame and mask (wall clock, which waits for the passes first).
  double ms_upload = 0, ms_gpu_passes = 0, ms_readback = 0;

  // "stitched 2048x1024 in 41.2 ms (valid 93.1 %), gains [1.02, ...], unused cameras: 3".
  std::string Summary() const;
};

struct StitchedFrame {
  sphere::EquirectImage image;      // linear RGB
  std::vector<std::uint8_t> valid;  // per pixel: 1 where a used camera saw it
  StitchReport report;
};

// Choosing the scene distance from the frames: each candidate's lookup table is built at a
// reduced size and the cameras' gain-corrected samples are compared where they overlap. The
// score of a candidate is the RMS (linear RGB) of each camera's sample from the overlap's
// feathered blend, each output pixel weighted by its solid angle (cos latitude), so the
// equirect's stretched poles do not outvote the horizon; the lower, the less the seams
// disagree. Pixels where a camera is clipped (exposure says nothing there) and cameras left out
// of the stitch (missing or black frames) take no part. Over several frame sets a candidate's
// score is the mean of theirs.
//
// Infinity is always among the candidates and is kept, with a reason, unless the best one lowers
// its score by at least min_improvement: with too few overlap samples (cameras that do not
// overlap, all black but one) there is no evidence, and where the score barely depends on the
// distance (a textureless or distant scene, sky-only overlaps) infinity is right for the far
// scene and costs the near one nothing measurable.
struct SceneDistanceSearch {
  // Metres; 0 = infinity. A geometric ladder: parallax goes with 1 / distance, so the steps are
  // even in what they change at the seams.
  std::vector<double> candidates_m = {2, 3, 5, 8, 12, 20, 40, 0};
  int width = 512;  // of the reduced lookup tables (height width / 2)
  double min_improvement = 0.03;
  long min_samples = 500;  // overlap samples (over all frame sets) below which infinity is kept

  // Throws odvr::UsageError naming the bad field.
  void Check() const;
};

struct SceneDistanceChoice {
  double distance_m = 0;             // the choice; 0 = infinity
  std::vector<double> candidates_m;  // as scored (0 = infinity)
  std::vector<double> scores;        // per candidate: RMS disagreement (NaN: no overlap sample)
  std::vector<long> samples;         // per candidate: overlap pixels scored, over all frame sets
  int frame_sets = 0;                // frame sets scored
  std::string reason;                // why infinity was kept (empty when chosen by score)
  double ms = 0;

  // "scene distance 8 m (seam RMS 2 m 0.0412, ..., inf 0.0455; 1 frame set, 95 ms)".
  std::string Summary() const;
};

// Scores `frame_sets` (each one image per camera, as Stitcher::Stitch takes them) at every
// candidate with `options`' gains, feather and prefilter settings (its size, device, fill and
// distance are not used; the scoring runs on the CPU). Throws odvr::Error for frame sets the
// stitcher would refuse, odvr::UsageError for bad options.
SceneDistanceChoice ChooseSceneDistance(const Rig& rig, const std::vector<std::vector<cv::Mat>>& frame_sets,
                                        const StitchOptions& options, const SceneDistanceSearch& search = {});

class Source;
// The choice for a clip, as `odvr stitch --scene-distance auto` makes it: from up to `sets` frame
// sets spread evenly over frames [first, first + frames) of a recording (frames 0: to its end),
// read through Seek, after which the source is left at `first`; a single frame can be
// unrepresentative (a passing lorry, a camera still adjusting its exposure). Returns nullopt,
// reading nothing, for a live source or one that cannot seek: choose from its first set then.
std::optional<SceneDistanceChoice> ChooseSceneDistanceForRecording(const Rig& rig, Source* source, long first,
                                                                   long frames, const StitchOptions& options,
                                                                   int sets = 3,
                                                                   const SceneDistanceSearch& search = {});

class Stitcher {
 public:
  // Builds the lookup table (and, for the GPU, the programs and buffers: a GL 4.5 context must
  // be current, and stay current for every Stitch call). Throws odvr::Error / UsageError.
  Stitcher(const Rig& rig, const StitchOptions& options);
  ~Stitcher();
  Stitcher(const Stitcher&) = delete;
  Stitcher& operator=(const Stitcher&) = delete;

  // `images[c]` is camera c's 8-bit BGR frame (OpenCV's order), or empty when missing.
  StitchedFrame Stitch(const std::vector<cv::Mat>& images);
  StitchedFrame Stitch(const FrameSet& set);
  // The same into `out`, reusing its buffers when they already have the output's size, so a
  // video loop does not allocate (and fault in) a frame's memory per frame.
  void Stitch(const std::vector<cv::Mat>& images, StitchedFrame* out);

  const StitchLut& lut() const;
  const StitchOptions& options() const;
  double lut_build_ms() const;

 private:
  friend SceneDistanceChoice ChooseSceneDistance(const Rig&, const std::vector<std::vector<cv::Mat>>&,
                                                 const StitchOptions&, const SceneDistanceSearch&);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace odvr::capture
