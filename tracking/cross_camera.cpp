#include "tracking/cross_camera.h"

#include <Eigen/Geometry>
#include <cmath>
#include <opencv2/features2d.hpp>

#include "core/error.h"

namespace odvr::tracking {
namespace {

struct Described {
  cv::Mat descriptors;      // one row per kept point
  std::vector<int> points;  // index into the view's points per row
};

Described Describe(const CameraTrackPoints& view, const CrossCameraOptions& options) {
  Described out;
  if (view.pixels.empty() || view.gray.empty()) return out;
  std::vector<cv::KeyPoint> keypoints;
  for (size_t i = 0; i < view.pixels.size(); ++i) {
    // Angle 0: the rig's cameras all stand upright (camera up = rig up), so orientation-free
    // descriptors lose nothing and discriminate better than rotation-invariant ones.
    keypoints.emplace_back(cv::Point2f(static_cast<float>(view.pixels[i].x()), static_cast<float>(view.pixels[i].y())),
                           options.keypoint_size_px, 0.f, 0.f, 0, static_cast<int>(i));
  }
  static thread_local cv::Ptr<cv::SIFT> sift = cv::SIFT::create();
  sift->compute(view.gray, keypoints, out.descriptors);
  for (const auto& k : keypoints) out.points.push_back(k.class_id);
  return out;
}

// For each row of `from`, the best row of `to` when it passes the ratio test, else -1.
std::vector<int> RatioMatches(const cv::Mat& from, const cv::Mat& to, double ratio) {
  std::vector<int> best(from.rows, -1);
  if (from.empty() || to.rows < 2) return best;
  cv::BFMatcher matcher(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(from, to, knn, 2);
  for (const auto& m : knn)
    if (m.size() == 2 && m[0].distance < ratio * m[1].distance) best[m[0].queryIdx] = m[0].trainIdx;
  return best;
}

}  // namespace

void CrossCameraOptions::Check() const {
  if (!(ratio > 0 && ratio <= 1)) throw Error("cross-camera ratio", "must be in (0, 1]");
  if (!(max_epipolar_deg > 0)) throw Error("cross-camera max_epipolar_deg", "must be > 0");
  if (!(max_parallax_deg > 0)) throw Error("cross-camera max_parallax_deg", "must be > 0");
  if (!(max_axis_angle_deg > 0 && max_axis_angle_deg <= 180))
    throw Error("cross-camera max_axis_angle_deg", "must be in (0, 180]");
  if (!(keypoint_size_px >= 4)) throw Error("cross-camera keypoint_size_px", "must be >= 4");
}

std::vector<CrossCameraMatch> MatchAcrossCameras(const RigGeometry& rig, const std::vector<CameraTrackPoints>& views,
                                                 const CrossCameraOptions& options, CrossCameraStats* stats) {
  options.Check();
  CrossCameraStats local;
  std::vector<Described> described;
  for (const auto& v : views) {
    if (v.camera < 0 || v.camera >= rig.camera_count())
      throw Error("cross-camera matching", "camera " + std::to_string(v.camera) + " is not in the rig");
    if (v.ids.size() != v.pixels.size() || v.bearings.size() != v.pixels.size())
      throw Error("cross-camera matching",
                  "camera " + std::to_string(v.camera) + ": ids, pixels and bearings differ in count");
    described.push_back(Describe(v, options));
  }
  const double cos_axis = std::cos(options.max_axis_angle_deg * M_PI / 180);
  const double max_epipolar = options.max_epipolar_deg * M_PI / 180;
  const double max_parallax = options.max_parallax_deg * M_PI / 180;
  std::vector<CrossCameraMatch> matches;
  for (size_t a = 0; a < views.size(); ++a)
    for (size_t b = a + 1; b < views.size(); ++b) {
      const Rigid3& ca = rig.rig_from_cam[views[a].camera];
      const Rigid3& cb = rig.rig_from_cam[views[b].camera];
      if (ca.rotation.col(2).dot(cb.rotation.col(2)) < cos_axis) continue;
      if (described[a].descriptors.empty() || described[b].descriptors.empty()) continue;
      const std::vector<int> ab = RatioMatches(described[a].descriptors, described[b].descriptors, options.ratio);
      const std::vector<int> ba = RatioMatches(described[b].descriptors, described[a].descriptors, options.ratio);
      for (size_t i = 0; i < ab.size(); ++i) {
        const int j = ab[i];
        if (j < 0) continue;
        ++local.ratio_passed;
        if (ba[j] != static_cast<int>(i)) continue;
        ++local.cross_checked;
        const int pa = described[a].points[i], pb = described[b].points[j];
        const Eigen::Vector3d da = ca.rotation * views[a].bearings[pa];
        const Eigen::Vector3d db = cb.rotation * views[b].bearings[pb];
        if (std::atan2(da.cross(db).norm(), da.dot(db)) > max_parallax) continue;
        if (!(TwoRayAngularError(ca.translation, da, cb.translation, db) <= max_epipolar)) continue;
        ++local.epipolar_passed;
        matches.push_back({views[a].ids[pa], views[b].ids[pb], views[a].camera, views[b].camera});
      }
    }
  if (stats) {
    stats->ratio_passed += local.ratio_passed;
    stats->cross_checked += local.cross_checked;
    stats->epipolar_passed += local.epipolar_passed;
  }
  return matches;
}

}  // namespace odvr::tracking
