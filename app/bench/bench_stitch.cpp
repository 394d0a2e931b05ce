// odvr bench stitch: the stitcher against the street_a ground-truth panoramas, beside
// OpenCV's own stitching pipeline given the same known calibration. Time per frame and PSNR
// (8-bit sRGB, over the valid mask and over the seams alone) side by side; writes a Markdown
// table, the raw rows (TSV) and a PNG plot of PSNR against time.
//
// OpenCV gets what a user with a calibrated rig would give it: each camera warped into the
// equirect by cv::remap through maps built once from our lookup table (the same geometry, so the
// comparison is about exposure compensation and blending, not calibration), then
// cv::detail::GainCompensator and cv::detail::MultiBandBlender, as stitching_detailed.cpp uses
// them, on OpenCV's 8-bit sRGB images.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/stitching/detail/blenders.hpp>
#include <opencv2/stitching/detail/exposure_compensate.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "app/bench/bench_common.h"
#include "app/bench/bench_stitch.h"
#include "app/flags/command_flags.h"
#include "capture/rig.h"
#include "capture/stitcher.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/srgb.h"
#include "core/timing.h"
#include "engine/gl/context.h"
#include "engine/image/image_io.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Where an odvr stitch's time goes (capture::StitchReport), each the median of the repeats.
constexpr std::array<const char*, 7> kStageNames = {"prepare", "gains",      "warp",    "fill",
                                                    "upload",  "gpu_passes", "readback"};
using Stages = std::array<double, kStageNames.size()>;

Stages StagesOf(const capture::StitchReport& r) {
  return {r.ms_prepare, r.ms_gains, r.ms_warp, r.ms_fill, r.ms_upload, r.ms_gpu_passes, r.ms_readback};
}

struct Row {
  int frame = 0;
  std::string method;
  double ms = 0;  // median of the repeats
  double psnr_valid = 0, psnr_seams = 0;
  bool has_stages = false;  // the odvr paths
  Stages stages{};
};

// Rows are kept at the precision the TSV prints them with, so the table and the target lines,
// computed from the rows in memory, say exactly what a reader recomputes from the TSV.
double RoundTo(double v, double per_unit) { return std::round(v * per_unit) / per_unit; }

cv::Mat ToBgr8(const sphere::EquirectImage& img) {
  cv::Mat out(img.height, img.width, CV_8UC3);
  for (int y = 0; y < img.height; ++y) {
    auto* row = out.ptr<cv::Vec3b>(y);
    for (int x = 0; x < img.width; ++x)
      for (int k = 0; k < 3; ++k)
        row[x][2 - k] = static_cast<unsigned char>(std::lround(255.0f * LinearToSrgb(img.at(x, y)[k])));
  }
  return out;
}

// PSNR of two 8-bit images over the pixels where `mask` is non-zero.
double Psnr(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  diff.convertTo(diff, CV_64FC3);
  diff = diff.mul(diff);
  const cv::Scalar se = cv::sum(diff.setTo(cv::Scalar::all(0), mask == 0));
  const double n = cv::countNonZero(mask);
  if (n == 0) return 0;
  const double mse = (se[0] + se[1] + se[2]) / (3.0 * n);
  return mse > 0 ? 10 * std::log10(255.0 * 255.0 / mse) : 99.0;
}

// The masks every method is scored on, from the lookup table: `valid` where a camera sees the
// direction, `seams` where two cameras both see it at least 10 % in from their image edges by a
// tent measure (the product over both axes of the distance to the nearer edge over the
// half-size exceeds 0.1: where blending and exposure differences show). The tent is fixed here
// rather than taken from the stitcher's own feather weights, so the mask stays the same
// whatever feather the stitcher uses.
void ScoreMasks(const capture::Rig& rig, const capture::StitchLut& lut, cv::Mat* valid, cv::Mat* seams) {
  *valid = cv::Mat::zeros(lut.height, lut.width, CV_8U);
  *seams = cv::Mat::zeros(lut.height, lut.width, CV_8U);
  for (std::size_t p = 0; p < lut.pixel_count(); ++p) {
    int strong = 0;
    for (auto e = lut.offsets[p]; e < lut.offsets[p + 1]; ++e) {
      const auto& entry = lut.entries[e];
      const auto& model = rig.cameras[entry.camera].model;
      strong += capture::FeatherWeight(entry.u, entry.v, model.width(), model.height(), 1.0) > 0.1f;
    }
    valid->data[p] = lut.offsets[p + 1] > lut.offsets[p] ? 255 : 0;
    seams->data[p] = strong >= 2 ? 255 : 0;
  }
}

// OpenCV's pipeline with the rig's calibration, used the way stitching_detailed.cpp uses it.
// The remap maps are built once per rig (as our lookup table is). Per frame:
//  * gains: GainCompensator fed with every camera warped over the whole panorama at a quarter of
//    the output size. stitching_detailed also estimates exposure on a smaller warp (seam_megapix);
//    a quarter matches the density of our own estimate (every 4th output pixel each way), and
//    full-width images keep the overlaps across the longitude seam;
//  * warp: cv::remap over each camera's footprint only, as a cv::detail warper returns an image
//    of its footprint's bounding box and not of the whole panorama;
//  * the gains applied, then MultiBandBlender.
class OpenCvStitcher {
 public:
  static constexpr int kGainScale = 4;

  explicit OpenCvStitcher(const capture::StitchLut& lut) : width_(lut.width), height_(lut.height) {
    const int n = lut.cameras;
    const int gw = std::max(1, width_ / kGainScale), gh = std::max(1, height_ / kGainScale);
    std::vector<cv::Mat> map_x(static_cast<std::size_t>(n)), map_y(static_cast<std::size_t>(n));
    std::vector<cv::Mat> gain_x(static_cast<std::size_t>(n)), gain_y(static_cast<std::size_t>(n));
    cameras_.resize(static_cast<std::size_t>(n));
    for (int c = 0; c < n; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      map_x[cu] = cv::Mat(height_, width_, CV_32F, cv::Scalar(-1));
      map_y[cu] = cv::Mat(height_, width_, CV_32F, cv::Scalar(-1));
      gain_x[cu] = cv::Mat(gh, gw, CV_32F, cv::Scalar(-1));
      gain_y[cu] = cv::Mat(gh, gw, CV_32F, cv::Scalar(-1));
      cameras_[cu].mask = cv::Mat::zeros(height_, width_, CV_8U);
      cameras_[cu].gain_mask = cv::Mat::zeros(gh, gw, CV_8U);
    }
    for (std::size_t p = 0; p < lut.pixel_count(); ++p) {
      const int row = static_cast<int>(p / static_cast<std::size_t>(width_));
      const int col = static_cast<int>(p % static_cast<std::size_t>(width_));
      // The quarter-size warp samples the output pixel at the centre of each 4x4 block.
      const bool gain_sample = row % kGainScale == kGainScale / 2 && col % kGainScale == kGainScale / 2 &&
                               row / kGainScale < gh && col / kGainScale < gw;
      for (auto e = lut.offsets[p]; e < lut.offsets[p + 1]; ++e) {
        const auto& entry = lut.entries[e];
        map_x[entry.camera].ptr<float>()[p] = entry.u;
        map_y[entry.camera].ptr<float>()[p] = entry.v;
        cameras_[entry.camera].mask.data[p] = 255;
        if (gain_sample) {
          gain_x[entry.camera].at<float>(row / kGainScale, col / kGainScale) = entry.u;
          gain_y[entry.camera].at<float>(row / kGainScale, col / kGainScale) = entry.v;
          cameras_[entry.camera].gain_mask.at<uchar>(row / kGainScale, col / kGainScale) = 255;
        }
      }
    }
    for (int c = 0; c < n; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      Camera& cam = cameras_[cu];
      // Fixed-point maps: what cv::remap users pick for speed (and what the warpers build).
      cv::convertMaps(map_x[cu], map_y[cu], cam.map1, cam.map2, CV_16SC2);
      cv::convertMaps(gain_x[cu], gain_y[cu], cam.gain_map1, cam.gain_map2, CV_16SC2);
      cam.pieces = Pieces(cam.mask);
      cam.gain_umask = cam.gain_mask.getUMat(cv::ACCESS_READ);
    }
    // stitching_detailed.cpp's band count for a 5 % blend strength.
    const double blend_width = std::sqrt(static_cast<double>(width_) * height_) * 5 / 100;
    bands_ = std::max(1, static_cast<int>(std::ceil(std::log(blend_width) / std::log(2.0))) - 1);
  }

  cv::Mat Stitch(const std::vector<cv::Mat>& images) const {
    const std::size_t n = cameras_.size();
    std::vector<cv::UMat> small(n);
    std::vector<cv::Point> corners(n, cv::Point(0, 0));
    std::vector<std::pair<cv::UMat, uchar>> masks(n);
    for (std::size_t c = 0; c < n; ++c) {
      cv::remap(images[c], small[c], cameras_[c].gain_map1, cameras_[c].gain_map2, cv::INTER_LINEAR,
                cv::BORDER_CONSTANT);
      masks[c] = {cameras_[c].gain_umask, 255};
    }
    cv::detail::GainCompensator compensator;
    compensator.feed(corners, small, masks);
    cv::detail::MultiBandBlender blender(false, bands_);
    blender.prepare(cv::Rect(0, 0, width_, height_));
    for (std::size_t c = 0; c < n; ++c)
      // The blender works on a plane: a camera whose footprint crosses the longitude seam goes in
      // as its two pieces, so no piece spans the whole width.
      for (const cv::Rect& r : cameras_[c].pieces) {
        cv::Mat warped;
        cv::remap(images[c], warped, cameras_[c].map1(r), cameras_[c].map2(r), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
        compensator.apply(static_cast<int>(c), r.tl(), warped, cameras_[c].mask(r));
        blender.feed(warped, cameras_[c].mask(r), r.tl());
      }
    cv::Mat result, result_mask, out;
    blender.blend(result, result_mask);
    result.convertTo(out, CV_8U);
    return out;
  }

  int bands() const { return bands_; }

 private:
  struct Camera {
    cv::Mat map1, map2, mask;
    cv::Mat gain_map1, gain_map2, gain_mask;
    cv::UMat gain_umask;
    std::vector<cv::Rect> pieces;
  };

  // The footprint's column ranges: one bounding box, or two when it wraps around the seam.
  std::vector<cv::Rect> Pieces(const cv::Mat& mask) const {
    cv::Mat columns;
    cv::reduce(mask, columns, 0, cv::REDUCE_MAX);
    std::vector<bool> used(static_cast<std::size_t>(width_));
    for (int x = 0; x < width_; ++x) used[static_cast<std::size_t>(x)] = columns.at<uchar>(0, x) > 0;
    std::vector<cv::Rect> out;
    for (int x = 0; x < width_;) {
      if (!used[static_cast<std::size_t>(x)]) {
        ++x;
        continue;
      }
      int end = x;
      while (end < width_ && used[static_cast<std::size_t>(end)]) ++end;
      const cv::Rect cols(x, 0, end - x, height_);
      const cv::Rect box = cv::boundingRect(mask(cols)) + cols.tl();
      if (!box.empty()) out.push_back(box);
      x = end;
    }
    return out;
  }

  int width_, height_, bands_ = 5;
  std::vector<Camera> cameras_;
};

std::vector<cv::Mat> LoadRigFrame(const fs::path& dataset, const capture::Rig& rig, int frame) {
  char name[32];
  std::snprintf(name, sizeof name, "%06d.jpg", frame);
  std::vector<cv::Mat> images;
  for (const auto& cam : rig.cameras) {
    const fs::path path = dataset / cam.image_dir / name;
    images.push_back(cv::imread(path.string(), cv::IMREAD_COLOR));
    if (images.back().empty()) throw Error(path.string(), "cannot read the rig image");
  }
  return images;
}

// The figures the targets are set on, computed from the rows (never typed in by hand).
std::string Targets(const std::vector<Row>& rows, const BenchStitchOptions& o, const std::string& gpu_renderer) {
  std::map<int, std::map<std::string, const Row*>> by_frame;
  for (const auto& r : rows) by_frame[r.frame][r.method] = &r;
  std::vector<double> speedup, d_valid, d_seams, gpu_ms;
  for (const auto& [frame, methods] : by_frame) {
    const auto cpu = methods.find("odvr cpu"), cv = methods.find("opencv"), gpu = methods.find("odvr gpu");
    if (cpu != methods.end() && cv != methods.end()) {
      speedup.push_back(cv->second->ms / cpu->second->ms);
      d_valid.push_back(cpu->second->psnr_valid - cv->second->psnr_valid);
      d_seams.push_back(cpu->second->psnr_seams - cv->second->psnr_seams);
    }
    if (gpu != methods.end()) gpu_ms.push_back(gpu->second->ms);
  }
  std::ostringstream md;
  md << "\n## Targets, from the rows above\n\n";
  if (!speedup.empty()) {
    // PSNR is printed to 0.01 dB and the frames differ by tenths: "equal" allows 0.05 dB.
    constexpr double kEqualDb = 0.05;
    const double s = Median(speedup), dv = Median(d_valid), ds = Median(d_seams);
    const auto at_least = [](const std::vector<double>& v, double floor) {
      return std::count_if(v.begin(), v.end(), [floor](double x) { return x >= floor; });
    };
    const bool met = s >= 5 && dv >= -kEqualDb && ds >= -kEqualDb;
    md << "**CPU path ≥ 5× faster than OpenCV's pipeline at equal or better PSNR: " << (met ? "met" : "not met")
       << ".** Speed-up of `odvr cpu` over `opencv`: " << fmt::format("{:.1f}", s) << "× (median over the frames "
       << "of the per-frame ratio of times; ≥ 5× on " << at_least(speedup, 5) << " of " << speedup.size()
       << " frames). PSNR of `odvr cpu` minus that of `opencv`: " << fmt::format("{:+.2f}", dv)
       << " dB over the valid mask, " << fmt::format("{:+.2f}", ds) << " dB over the seams (medians; equal or "
       << "better, within " << kEqualDb << " dB, on " << at_least(d_valid, -kEqualDb) << " and "
       << at_least(d_seams, -kEqualDb) << " of " << d_valid.size() << " frames).\n\n";
  }
  if (gpu_ms.empty()) {
    md << "**GPU:** not timed (run with `--gpu`).\n";
  } else {
    const double ms = Median(gpu_ms);
    md << "**GPU (" << gpu_renderer << "):** median " << fmt::format("{:.1f}", ms) << " ms per " << o.width << "×"
       << o.height << " frame (" << fmt::format("{:.1f}", 1000 / ms) << " frames per second), from upload to "
       << "read-back, with the gain estimate on the CPU. The seed stitches 6 × 1600×1200 at 25 fps: 40 ms per "
       << "frame; " << (ms <= 40 ? "within" : "outside") << " that budget here, at this output size and with "
       << "480×640 inputs.";
    if (gl::IsSoftwareRenderer(gpu_renderer))
      md << " No GPU machine was available for this run: llvmpipe is Mesa's software rasterizer on the same CPU "
            "cores, so the row shows that the GLSL path runs and matches the CPU path, not what a GPU reaches.";
    md << "\n";
  }
  return md.str();
}

void WriteReport(const std::vector<Row>& rows, const BenchStitchOptions& o, const std::string& machine,
                 const std::string& gpu_renderer, int bands) {
  fs::create_directories(o.out_dir);
  const fs::path tsv = fs::path(o.out_dir) / "stitch.tsv";
  std::ostringstream t;
  t << "frame\tmethod\tms\tpsnr_valid_db\tpsnr_seams_db\n";
  for (const auto& r : rows)
    t << fmt::format("{}\t{}\t{:.3f}\t{:.4f}\t{:.4f}\n", r.frame, r.method, r.ms, r.psnr_valid, r.psnr_seams);
  WriteTextAtomically(tsv, t.str());
  std::ostringstream st;
  st << "frame\tmethod";
  for (const char* name : kStageNames) st << "\t" << name << "_ms";
  st << "\n";
  for (const auto& r : rows) {
    if (!r.has_stages) continue;
    st << r.frame << "\t" << r.method;
    for (double v : r.stages) st << fmt::format("\t{:.3f}", v);
    st << "\n";
  }
  WriteTextAtomically(fs::path(o.out_dir) / "stitch_stages.tsv", st.str());

  std::map<std::string, std::vector<const Row*>> groups;
  std::vector<std::string> order;
  for (const auto& r : rows) {
    if (!groups.count(r.method)) order.push_back(r.method);
    groups[r.method].push_back(&r);
  }
  std::string frames;
  for (int f : o.frames) frames += (frames.empty() ? "" : ", ") + std::to_string(f);
  std::ostringstream md;
  md << "# Stitching: speed and error against the ground truth\n\n"
     << "Made by `odvr bench stitch" << (o.gpu ? " --gpu" : "") << "` on " << machine << ". Dataset `"
     << fs::path(o.dataset).filename().string()
     << "` (six 480×640 equidistant fisheyes with exposure gains 0.94–1.13 baked in), frames " << frames << ", output "
     << o.width << "×" << o.height << ", rays meeting at "
     << (o.scene_distance_m > 0 ? fmt::format("{} m", o.scene_distance_m) : std::string("infinity")) << ". "
     << "PSNR is in 8-bit sRGB against the rendered panorama from the rig centre (`pano/`), over the directions a "
     << "camera sees (`valid`) and over the seams alone (`seams`: where two cameras both see the direction with a "
     << "tent weight above 0.1, the tent falling from 1 at an image's centre to 0 at its edges). The renders carry "
        "Monte-Carlo noise of their own (~23 dB per image, the dataset's README), which "
     << "bounds every figure. Time is the median per frame over " << o.repeats << " runs of each of the "
     << o.frames.size() << " frames, after a warm-up; lookup tables and remap maps are built once per rig and not "
     << "timed. Every method runs on all cores (our thread pool, OpenCV's parallel_for_).\n\n"
     << "- `odvr cpu`: capture::Stitcher on the CPU (linearize, at half resolution where the output minifies a "
        "camera; gains from the overlaps; blend with weights that ramp up over the outer 10 % of each image; "
        "pull-push fill of the unseen caps), stitching into the same frame buffers each time.\n"
     << "- `odvr gpu`: the same on the GPU (GLSL compute), read back to the CPU.\n"
     << "- `opencv`: the same geometry (cv::remap maps built from our lookup table, so the comparison is about "
        "exposure and blending, not calibration), then OpenCV's own cv::detail::GainCompensator (fed a "
        "quarter-size warp, as stitching_detailed estimates exposure on a reduced warp) and "
        "cv::detail::MultiBandBlender ("
     << bands
     << " bands, stitching_detailed's count for its default 5 % blend strength) over each camera's footprint, "
        "no seam finder (the footprints overlap and the bands are blended across the overlaps), in OpenCV's "
        "8-bit sRGB.\n\n"
     << "| method | ms per frame | PSNR valid (dB) | PSNR seams (dB) | speed-up vs opencv |\n"
     << "|---|---|---|---|---|\n";
  double opencv_ms = 0;
  if (groups.count("opencv")) {
    std::vector<double> v;
    for (const Row* r : groups["opencv"]) v.push_back(r->ms);
    opencv_ms = Median(v);
  }
  for (const auto& method : order) {
    std::vector<double> ms, pv, ps;
    for (const Row* r : groups[method]) {
      ms.push_back(r->ms);
      pv.push_back(r->psnr_valid);
      ps.push_back(r->psnr_seams);
    }
    const double m = Median(ms);
    md << "| " << method << " | " << fmt::format("{:.1f}", m) << " | " << fmt::format("{:.2f}", Median(pv)) << " | "
       << fmt::format("{:.2f}", Median(ps)) << " | "
       << (opencv_ms > 0 && m > 0 ? fmt::format("{:.1f}×", opencv_ms / m) : std::string("–")) << " |\n";
  }
  md << "\nMedians over the frames; every frame is in `stitch.tsv`.\n\n"
     << "Where an odvr frame's time goes (ms, medians over the frames of each stage's median over the runs, so "
        "they need not add up to the row above; every frame is in `stitch_stages.tsv`). *prepare*: the frames "
        "linearized on the CPU for the means and the gain estimate, which both devices use; *warp*: the blend, "
        "on the GPU the whole submission, which is *upload* (the frames into the texture array, wall clock), "
        "*GPU passes* (linearize, warp and pull-push fill on the GPU's own clock, GL timestamps) and *read-back* "
        "(the result read and converted to the frame and its mask, wall clock, waiting for the passes first); "
        "*fill*: the CPU's pull-push fill.\n\n"
     << "| method | prepare | gains | warp | fill | upload | GPU passes | read-back |\n"
     << "|---|---|---|---|---|---|---|---|\n";
  for (const auto& method : order) {
    std::vector<Stages> stages;
    for (const Row* r : groups[method])
      if (r->has_stages) stages.push_back(r->stages);
    if (stages.empty()) continue;
    md << "| " << method;
    for (std::size_t k = 0; k < kStageNames.size(); ++k) {
      std::vector<double> v;
      for (const Stages& s : stages) v.push_back(s[k]);
      md << fmt::format(" | {:.2f}", Median(v));
    }
    md << " |\n";
  }
  md << Targets(rows, o, gpu_renderer)
     << "\nThe plot `stitch.png` shows each frame's PSNR against its time per frame.\n\n"
        "![PSNR against time](stitch.png)\n";
  WriteTextAtomically(fs::path(o.out_dir) / "stitch.md", md.str());

  std::ostringstream gp;
  gp << "set datafile separator '\\t'\nset logscale x\nset key outside right\nset grid\n"
     << "set title 'stitching " << o.width << "x" << o.height
     << ": PSNR against the ground truth vs time per frame'\nset xlabel 'ms per frame'\nset ylabel 'PSNR (dB)'\nplot ";
  // One colour per method; filled points for the valid mask, open ones for the seams.
  bool first = true;
  for (std::size_t m = 0; m < order.size(); ++m)
    for (const auto& [col, what, shape] : {std::tuple{4, "valid", 7}, std::tuple{5, "seams", 6}}) {
      gp << (first ? "" : ", ") << "'" << tsv.filename().string() << "' using (strcol(2) eq '" << order[m]
         << "' ? $3 : 1/0):" << col << " with points pt " << shape << " ps 1.5 lc " << m + 1 << " title '" << order[m]
         << " (" << what << ")'";
      first = false;
    }
  gp << "\n";
  WritePlot(o.out_dir, "stitch", 900, 520, gp.str(), "bench stitch");
}

}  // namespace

int RunBenchStitch(const BenchStitchOptions& o) {
  const fs::path dataset = o.dataset;
  if (!fs::exists(dataset / "rig.json"))
    throw UsageError("--dataset", dataset.string() + " has no rig.json (is ../shared/data present?)");
  if (o.frames.empty()) throw UsageError("--frames", "needs at least one frame");
  const capture::Rig rig = capture::LoadRig(dataset / "rig.json");
  capture::StitchOptions so;
  so.width = o.width;
  so.height = o.height;
  so.scene_distance_m = o.scene_distance_m;
  so.Check();

  std::string machine = BenchMachineDescription(), gpu_renderer;
  // Times on a shared machine mean little without the load they were measured under.
  if (std::ifstream load("/proc/loadavg"); load) {
    double one_minute = 0;
    if (load >> one_minute) machine += fmt::format(" (1-minute load average {:.1f} at the start)", one_minute);
  }
  std::optional<gl::HeadlessContext> context;
  std::unique_ptr<capture::Stitcher> gpu;
  if (o.gpu) {
    context.emplace();
    gpu_renderer = context->Info().renderer;
    machine += ", GPU: " + gpu_renderer;
    capture::StitchOptions g = so;
    g.device = capture::StitchDevice::kGpu;
    gpu = std::make_unique<capture::Stitcher>(rig, g);
  }
  capture::Stitcher cpu(rig, so);
  const OpenCvStitcher opencv(cpu.lut());
  cv::Mat valid, seams;
  ScoreMasks(rig, cpu.lut(), &valid, &seams);

  std::vector<Row> rows;
  BenchProgress progress("bench stitch", static_cast<long>(o.frames.size()));
  for (int frame : o.frames) {
    const auto images = LoadRigFrame(dataset, rig, frame);
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", frame);
    cv::Mat truth = cv::imread((dataset / "pano" / name).string(), cv::IMREAD_COLOR);
    if (truth.empty()) throw Error((dataset / "pano" / name).string(), "cannot read the ground-truth panorama");
    if (truth.cols != o.width || truth.rows != o.height)
      cv::resize(truth, truth, cv::Size(o.width, o.height), 0, 0, cv::INTER_AREA);

    // Each method: one warm-up, then `repeats` timed runs of `run`; `result` (untimed) gives
    // the last frame as 8-bit sRGB BGR to score. The odvr paths are timed to their linear float
    // frame: the sRGB encoding belongs to the scoring.
    // `report`: the odvr paths' stage times after each run (null for OpenCV).
    const auto measure = [&](const std::string& method, const std::function<void()>& run,
                             const std::function<cv::Mat()>& result, const capture::StitchReport* report) {
      run();
      std::vector<double> times;
      std::vector<Stages> stages;
      for (int k = 0; k < o.repeats; ++k) {
        const auto t0 = Clock::now();
        run();
        times.push_back(MsSince(t0));
        if (report) stages.push_back(StagesOf(*report));
      }
      const cv::Mat out = result();
      Row row{frame, method, RoundTo(Median(times), 1e3), RoundTo(Psnr(out, truth, valid), 1e4),
              RoundTo(Psnr(out, truth, seams), 1e4)};
      row.has_stages = report != nullptr;
      if (report)
        for (std::size_t s = 0; s < kStageNames.size(); ++s) {
          std::vector<double> v;
          for (const Stages& st : stages) v.push_back(st[s]);
          row.stages[s] = RoundTo(Median(v), 1e3);
        }
      rows.push_back(row);
    };
    // As a video loop would, each path stitches into the same frame buffers every time.
    capture::StitchedFrame last;
    const auto last_bgr = [&] { return ToBgr8(last.image); };
    measure(
        "odvr cpu", [&] { cpu.Stitch(images, &last); }, last_bgr, &last.report);
    if (gpu)
      measure(
          "odvr gpu", [&] { gpu->Stitch(images, &last); }, last_bgr, &last.report);
    cv::Mat opencv_out;
    measure(
        "opencv", [&] { opencv_out = opencv.Stitch(images); }, [&] { return opencv_out; }, nullptr);
    progress.Step("frame " + std::to_string(frame));
  }
  WriteReport(rows, o, machine, gpu_renderer, opencv.bands());
  std::cout << "bench stitch: " << rows.size() << " rows; wrote " << o.out_dir
            << "/stitch.md, stitch.tsv, stitch_stages.tsv, stitch.png\n";
  return 0;
}

CommandFn AddBenchStitch(CLI::App* sub) {
  auto o = std::make_shared<BenchStitchOptions>();
  sub->add_option("--dataset", o->dataset, "A street_* dataset (rig.json, rig/, pano/)")->capture_default_str();
  sub->add_option("--frames", o->frames, "Frame indices to stitch")->delimiter(',')->capture_default_str();
  // The stitcher's own limits (StitchOptions::Check), named after these options.
  sub->add_option("--width", o->width, "Output equirect width")->capture_default_str()->check(CLI::Range(4, 32768));
  sub->add_option("--height", o->height, "Output equirect height")->capture_default_str()->check(CLI::Range(2, 16384));
  sub->add_option("--repeats", o->repeats, "Timed runs per frame and method (the median is kept)")
      ->check(CLI::Range(1, 100));
  sub->add_option("--scene-distance", o->scene_distance_m, "Metres at which camera rays meet (0 = infinity)");
  sub->add_flag("--gpu", o->gpu, "Also time the GPU path (needs an OpenGL 4.5 context)");
  sub->add_option("--out", o->out_dir, "Where the table, TSV and plot go (docs/benchmarks: the committed pages)")
      ->capture_default_str();
  return [o] { return RunBenchStitch(*o); };
}

}  // namespace odvr::app
