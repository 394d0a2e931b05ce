#include "tracking/tracks.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <sstream>

#include "core/error.h"

namespace odvr::tracking {

void KltOptions::Check() const {
  if (!(quality_level > 0 && quality_level < 1)) throw Error("klt quality_level", "must be in (0, 1)");
  if (!(min_distance_px >= 0)) throw Error("klt min_distance_px", "must be >= 0");
  if (block_size < 3 || block_size % 2 == 0) throw Error("klt block_size", "must be odd and >= 3");
  if (cell_size_px < 8) throw Error("klt cell_size_px", "must be >= 8");
  if (corners_per_cell < 1) throw Error("klt corners_per_cell", "must be >= 1");
  if (window_px < 5 || window_px % 2 == 0) throw Error("klt window_px", "must be odd and >= 5");
  if (pyramid_levels < 1 || pyramid_levels > 8) throw Error("klt pyramid_levels", "must be 1..8");
  if (max_lk_iterations < 1) throw Error("klt max_lk_iterations", "must be >= 1");
  if (!(max_forward_backward_px > 0)) throw Error("klt max_forward_backward_px", "must be > 0");
  if (!(presmooth_sigma_px >= 0 && presmooth_sigma_px <= 10))
    throw Error("klt presmooth_sigma_px", "must be in [0, 10]");
  if (border_px < 0) throw Error("klt border_px", "must be >= 0");
  if (!(max_angle_deg >= 0 && max_angle_deg <= 180)) throw Error("klt max_angle_deg", "must be in [0, 180]");
}

KltTracker::KltTracker(const capture::CameraModel& model, const KltOptions& options, const cv::Mat& ignore)
    : model_(model), options_(options) {
  options_.Check();
  // A window at the top pyramid level reaches window << (levels - 1) pixels: pad by that much.
  if (model_.type() == capture::CameraModelType::kEquirectangular)
    wrap_ = std::min(model_.width(), options_.window_px << (options_.pyramid_levels - 1));
  const int w = model_.width(), h = model_.height();
  const double max_theta = options_.max_angle_deg > 0
                               ? std::min(model_.max_theta(), options_.max_angle_deg * M_PI / 180)
                               : model_.max_theta();
  mask_ = cv::Mat::zeros(h, w, CV_8U);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      Eigen::Vector3d b;
      if (model_.Unproject(Eigen::Vector2d(x, y), &b) && std::acos(std::clamp(b.z(), -1.0, 1.0)) <= max_theta)
        mask_.at<uint8_t>(y, x) = 255;
    }
  // Keep LK windows and corner blocks off the invalid region and the image edge: erode the valid
  // region, then clear the frame (erode treats outside-the-image as valid).
  const int b = options_.border_px;
  if (b > 0) {
    cv::erode(mask_, mask_, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * b + 1, 2 * b + 1)));
    mask_.rowRange(0, std::min(b, h)).setTo(0);
    mask_.rowRange(std::max(0, h - b), h).setTo(0);
    if (wrap_ == 0) {  // an equirect image's side edges are no edge
      mask_.colRange(0, std::min(b, w)).setTo(0);
      mask_.colRange(std::max(0, w - b), w).setTo(0);
    }
  }
  if (!ignore.empty()) {
    if (ignore.cols != w || ignore.rows != h || ignore.type() != CV_8U)
      throw Error("klt mask", "is " + std::to_string(ignore.cols) + "x" + std::to_string(ignore.rows) +
                                  " but the camera model is " + model_.Describe() + " (an 8-bit image of its size)");
    mask_.setTo(0, ignore);
  }
  const int c = options_.cell_size_px;
  for (int y = 0; y < h; y += c)
    for (int x = 0; x < w; x += c)
      valid_cells_ += cv::countNonZero(mask_(cv::Rect(x, y, std::min(c, w - x), std::min(c, h - y)))) > 0;
}

bool KltTracker::Observe(Eigen::Vector2d pixel, TrackObservation* observation) const {
  if (wrap_ > 0 && std::isfinite(pixel.x())) {
    const double w = model_.width();
    pixel.x() = std::fmod(std::fmod(pixel.x(), w) + w, w);
    if (pixel.x() >= w - 0.5) pixel.x() -= w;  // x in [-0.5, w - 0.5): nearest column 0 .. w - 1
  }
  int x = static_cast<int>(std::lround(pixel.x()));
  const int y = static_cast<int>(std::lround(pixel.y()));
  if (wrap_ > 0) x = std::clamp(x, 0, mask_.cols - 1);
  if (!pixel.allFinite() || x < 0 || y < 0 || x >= mask_.cols || y >= mask_.rows) return false;
  if (mask_.at<uint8_t>(y, x) == 0) return false;
  observation->pixel = pixel;
  return model_.Unproject(pixel, &observation->bearing);
}

const KltFrameStats& KltTracker::AddFrame(const cv::Mat& image) {
  KltFrameStats stats;
  stats.frame = frame_count();
  const std::string where = "klt frame " + std::to_string(stats.frame);
  if (image.empty()) throw Error(where, "empty image");
  if (image.cols != model_.width() || image.rows != model_.height())
    throw Error(where, "image is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                           " but the camera model is " + model_.Describe());
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3))
    throw Error(where, "expected 8-bit gray or BGR");
  cv::Mat gray;
  if (image.channels() == 3)
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  else
    gray = image.clone();
  if (options_.presmooth_sigma_px > 0) {
    // An equirect frame is smoothed across its seam too.
    const int pad = wrap_ > 0 ? std::min(gray.cols, static_cast<int>(std::ceil(4 * options_.presmooth_sigma_px))) : 0;
    cv::Mat wrapped;
    cv::copyMakeBorder(gray, wrapped, 0, 0, pad, pad, cv::BORDER_WRAP);
    cv::GaussianBlur(wrapped, wrapped, cv::Size(0, 0), options_.presmooth_sigma_px);
    gray = wrapped.colRange(pad, pad + gray.cols).clone();
  }
  cv::Mat padded = gray;
  if (wrap_ > 0) cv::copyMakeBorder(gray, padded, 0, 0, wrap_, wrap_, cv::BORDER_WRAP);

  if (!previous_.empty() && !active_.empty()) {
    std::vector<cv::Point2f> from, to, back;
    const auto shift = static_cast<float>(wrap_);
    for (int t : active_) {
      const Eigen::Vector2d& p = tracks_[t].observations.back().pixel;
      from.emplace_back(static_cast<float>(p.x()) + shift, static_cast<float>(p.y()));
    }
    const cv::Size window(options_.window_px, options_.window_px);
    const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, options_.max_lk_iterations, 0.01);
    std::vector<uchar> status, status_back;
    std::vector<float> error;
    cv::calcOpticalFlowPyrLK(previous_, padded, from, to, status, error, window, options_.pyramid_levels - 1, criteria);
    cv::calcOpticalFlowPyrLK(padded, previous_, to, back, status_back, error, window, options_.pyramid_levels - 1,
                             criteria);
    std::vector<int> still_active;
    for (size_t i = 0; i < active_.size(); ++i) {
      Track& track = tracks_[active_[i]];
      TrackObservation obs;
      obs.frame = stats.frame;
      if (!status[i] || !Observe(Eigen::Vector2d(to[i].x - shift, to[i].y), &obs)) {
        ++stats.lost_lk;
        track.active = false;
      } else if (!status_back[i] ||
                 std::hypot(back[i].x - from[i].x, back[i].y - from[i].y) > options_.max_forward_backward_px) {
        ++stats.lost_forward_backward;
        track.active = false;
      } else {
        track.observations.push_back(obs);
        still_active.push_back(active_[i]);
        ++stats.continued;
      }
    }
    active_ = std::move(still_active);
  }
  Detect(gray, &stats);
  previous_ = padded;
  stats.active = static_cast<int>(active_.size());
  stats_.push_back(stats);
  return stats_.back();
}

void KltTracker::Detect(const cv::Mat& gray, KltFrameStats* stats) {
  const int w = gray.cols, h = gray.rows, c = options_.cell_size_px;
  const int cols = (w + c - 1) / c, rows = (h + c - 1) / c;
  std::vector<int> occupancy(cols * rows, 0);
  cv::Mat free_mask = mask_.clone();
  const int radius = static_cast<int>(std::ceil(options_.min_distance_px));
  for (int t : active_) {
    const Eigen::Vector2d& p = tracks_[t].observations.back().pixel;
    const int cx = std::clamp(static_cast<int>(p.x() + 0.5) / c, 0, cols - 1);
    const int cy = std::clamp(static_cast<int>(p.y() + 0.5) / c, 0, rows - 1);
    ++occupancy[cy * cols + cx];
    cv::circle(free_mask, cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y()))), radius,
               0, -1);
  }
  // The quality floor is global: goodFeaturesToTrack's own quality level is relative to the
  // strongest corner of the region it sees, which in a per-cell call would promote noise in a
  // blank cell to a "corner".
  cv::Mat eigen;
  cv::cornerMinEigenVal(gray, eigen, options_.block_size, 3);
  double strongest = 0;
  cv::minMaxLoc(eigen, nullptr, &strongest, nullptr, nullptr, mask_);
  const double floor = options_.quality_level * strongest;
  // A flat image (strongest == 0) has nothing to detect.
  for (int cy = 0; cy < rows && strongest > 0; ++cy)
    for (int cx = 0; cx < cols; ++cx) {
      if (occupancy[cy * cols + cx] > 0) continue;
      const cv::Rect cell(cx * c, cy * c, std::min(c, w - cx * c), std::min(c, h - cy * c));
      if (cv::countNonZero(free_mask(cell)) == 0) continue;
      std::vector<cv::Point2f> corners;
      cv::goodFeaturesToTrack(gray(cell), corners, options_.corners_per_cell, 1e-3, options_.min_distance_px,
                              free_mask(cell), options_.block_size);
      for (const cv::Point2f& corner : corners) {
        const cv::Point2f p = corner + cv::Point2f(static_cast<float>(cell.x), static_cast<float>(cell.y));
        const int px = static_cast<int>(std::lround(p.x)), py = static_cast<int>(std::lround(p.y));
        if (eigen.at<float>(py, px) < floor || free_mask.at<uint8_t>(py, px) == 0) continue;
        Track track;
        track.id = static_cast<int>(tracks_.size());
        TrackObservation obs;
        obs.frame = stats->frame;
        if (!Observe(Eigen::Vector2d(p.x, p.y), &obs)) continue;
        track.observations.push_back(obs);
        active_.push_back(track.id);
        tracks_.push_back(std::move(track));
        ++stats->detected;
        ++occupancy[cy * cols + cx];
        // Keeps corners of the neighbouring cells min_distance away from this one too.
        cv::circle(free_mask, cv::Point(px, py), radius, 0, -1);
      }
    }
  int covered = 0;
  for (int v : occupancy) covered += v > 0;
  stats->covered_cells = valid_cells_ > 0 ? static_cast<double>(covered) / valid_cells_ : 0.0;
}

double KltTracker::MeanTrackLength() const {
  if (tracks_.empty()) return 0;
  double sum = 0;
  for (const Track& t : tracks_) sum += t.length();
  return sum / static_cast<double>(tracks_.size());
}

std::string KltTracker::BriefReport() const {
  std::ostringstream s;
  s << tracks_.size() << " tracks over " << frame_count() << " frames, mean length " << MeanTrackLength() << ", "
    << active_.size() << " active";
  if (!stats_.empty()) s << ", " << static_cast<int>(100 * stats_.back().covered_cells + 0.5) << " % cells covered";
  return s.str();
}

}  // namespace odvr::tracking
