#include "tracking/reconstruction.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <unordered_map>

#include "core/error.h"
#include "core/timing.h"
#include "tracking/central_pose.h"
#include "tracking/ransac.h"
#include "tracking/reconstruction_chunks.h"
#include "tracking/triangulation.h"
#include "tracking/trifocal.h"

namespace odvr::tracking {
namespace {

using Clock = std::chrono::steady_clock;

std::string Fixed(double v, int digits = 2) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

// One KLT tracker run of one camera: a camera that misses a frame starts a new segment, since LK
// cannot bridge a hole in its own sequence.
struct Segment {
  int camera = 0;
  int first_frame = 0;  // sequence frame of the tracker's frame 0
  std::unique_ptr<KltTracker> tracker;
  size_t colored = 0;  // tracks whose colour is sampled
  std::vector<std::array<unsigned char, 3>> colors;
};

long TrackKey(int segment, int track) { return (static_cast<long>(segment) << 24) | track; }

struct UnionFind {
  std::unordered_map<long, long> parent;
  long Find(long x) {
    auto it = parent.find(x);
    if (it == parent.end()) return x;
    const long root = Find(it->second);
    parent[x] = root;
    return root;
  }
  bool Union(long a, long b) {
    a = Find(a), b = Find(b);
    if (a == b) return false;
    parent[std::max(a, b)] = std::min(a, b);
    return true;
  }
};

struct Obs {
  int frame = 0;
  int camera = 0;
  Eigen::Vector2d pixel;
  Eigen::Vector3d bearing;
  bool inlier = true;
};

struct MapPoint {
  std::vector<Obs> obs;
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  bool triangulated = false;
  std::array<unsigned char, 3> rgb{};
};

struct UsedFrame {
  long index = 0;
  double timestamp = 0;
  int duplicate_of = -1;  // into the output frame list
};

CamFromWorld CamPose(const RigGeometry& rig, const Rigid3& world_from_rig, int camera) {
  const Rigid3 cam_from_world = rig.rig_from_cam[camera].Inverse() * world_from_rig.Inverse();
  CamFromWorld p;
  p.rotation = cam_from_world.rotation;
  p.translation = cam_from_world.translation;
  return p;
}

double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

// A trifocal datum whose residual is in pixels: the normalized-plane error times the pixels one
// normalized unit spans at the point's angle from the axis.
struct PixelTriple {
  PointTriple triple;
  double px_per_unit = 1;
};

struct PixelTrifocalEstimator {
  using Datum = PixelTriple;
  using Model = TrifocalTensor;
  static constexpr int kMinimalSample = TrifocalEstimator::kMinimalSample;

  std::vector<Model> Estimate(const std::vector<Datum>& data) const {
    std::vector<PointTriple> triples;
    triples.reserve(data.size());
    for (const auto& d : data) triples.push_back(d.triple);
    return TrifocalEstimator().Estimate(triples);
  }
  void Residuals(const std::vector<Datum>& data, const Model& model, std::vector<double>* residuals) const {
    residuals->resize(data.size());
    for (size_t i = 0; i < data.size(); ++i)
      (*residuals)[i] = model.ReprojectionError(data[i].triple) * data[i].px_per_unit;
  }
};

class Reconstructor {
 public:
  Reconstructor(const capture::Rig& rig, const ReconstructionOptions& options, const ReconstructionCallbacks& callbacks)
      : options_(options), callbacks_(callbacks), geometry_(RigGeometry::FromRig(rig)) {
    out_.rig = rig;
    out_.rig_height_m = options.rig_height_m > 0 ? options.rig_height_m : rig.height_m;
    out_.scale_source = options.rig_height_m > 0 ? "rig height given on the command line"
                        : rig.height_m > 0       ? "rig_height_m of " + rig.path.string()
                                                 : "";
    double f = 0;
    for (double v : geometry_.focal_px) f += v;
    focal_ = f / static_cast<double>(geometry_.focal_px.size());
  }

  Reconstruction Run(capture::Source& source) {
    if (geometry_.camera_count() == 0) throw Error(out_.rig.path.string(), "the rig has no cameras");
    if (source.camera_count() != geometry_.camera_count())
      throw Error("frames", "the source delivers " + std::to_string(source.camera_count()) +
                                " cameras but the rig file " + out_.rig.path.string() + " describes " +
                                std::to_string(geometry_.camera_count()));
    Track(source);
    CheckTrifocal();
    BuildPoints();
    SelectKeyFrames();
    Initialize();
    RegisterAll();
    Finish();
    return std::move(out_);
  }

 private:
  void Log(const std::string& line) const {
    if (callbacks_.log) callbacks_.log(line);
  }
  void Progress(const std::string& stage, int done, int total) const {
    if (callbacks_.progress) callbacks_.progress(stage, done, total);
  }
  void Stage(const std::string& name, Clock::time_point since, int inliers, const std::string& what) {
    out_.stages.push_back({name, SecondsSince(since), inliers, what});
    Log(name + ": " + std::to_string(inliers) + " " + what + " (" + Fixed(out_.stages.back().seconds) + " s)");
  }

  // --- tracking and cross-camera links -------------------------------------------------------

  void Track(capture::Source& source) {
    const auto t0 = Clock::now();
    const int cameras = geometry_.camera_count();
    std::vector<int> open(cameras, -1);  // current segment per camera
    std::vector<cv::Mat> previous(cameras);
    std::vector<bool> size_checked(cameras, false);
    const long total = options_.max_frames > 0 ? options_.max_frames : source.frame_count();
    long read = 0;
    while (options_.max_frames == 0 || read < options_.max_frames) {
      auto set = source.Next();
      if (!set) break;
      ++read;
      for (const auto& e : source.TakeEvents()) out_.warnings.push_back(e.message);
      long index = -1;
      double timestamp = 0;
      bool any = false;
      for (const auto& f : set->frames)
        if (!f.image.empty()) {
          any = true;
          index = f.index;
          timestamp = f.timestamp_s;
        }
      if (!any) {
        // No camera delivered: the rig frame does not exist; trackers carry on across the gap.
        out_.dropped_frames.push_back(set->frames.empty() ? set->index : set->frames.front().index);
        continue;
      }
      for (int c = 0; c < cameras; ++c) {
        const cv::Mat& image = set->frames[c].image;
        if (image.empty() || size_checked[c]) continue;
        const auto& model = out_.rig.cameras[c].model;
        if (image.cols != model.width() || image.rows != model.height())
          throw Error("camera " + out_.rig.cameras[c].name,
                      "images are " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                          " but the rig file " + out_.rig.path.string() + " says " + std::to_string(model.width()) +
                          "x" + std::to_string(model.height()));
        size_checked[c] = true;
      }
      // A duplicated frame (every delivered image equal to the previous one) adds no geometry and
      // would look like a rig that stopped: it takes the previous frame's pose.
      if (!used_.empty()) {
        bool duplicate = true;
        for (int c = 0; c < cameras && duplicate; ++c) {
          const cv::Mat& image = set->frames[c].image;
          if (image.empty()) continue;
          duplicate = !previous[c].empty() && previous[c].size() == image.size() &&
                      previous[c].type() == image.type() && cv::norm(previous[c], image, cv::NORM_INF) == 0;
        }
        if (duplicate) {
          duplicates_.push_back({index, timestamp, static_cast<int>(used_.size()) - 1});
          out_.warnings.push_back("frame " + std::to_string(index) + " repeats frame " +
                                  std::to_string(used_.back().index) + ": it takes that frame's pose");
          continue;
        }
      }
      const int k = static_cast<int>(used_.size());
      used_.push_back({index, timestamp, -1});
      std::vector<CameraTrackPoints> views;
      for (int c = 0; c < cameras; ++c) {
        const cv::Mat& image = set->frames[c].image;
        if (image.empty()) {
          open[c] = -1;  // the next image starts a new segment
          continue;
        }
        previous[c] = image;
        if (open[c] < 0) {
          Segment s;
          s.camera = c;
          s.first_frame = k;
          s.tracker = std::make_unique<KltTracker>(
              out_.rig.cameras[c].model, options_.klt,
              static_cast<size_t>(c) < options_.ignore_masks.size() ? options_.ignore_masks[c] : cv::Mat());
          segments_.push_back(std::move(s));
          open[c] = static_cast<int>(segments_.size()) - 1;
        }
        Segment& s = segments_[open[c]];
        s.tracker->AddFrame(image);
        const int local = s.tracker->frame_count() - 1;
        const auto& tracks = s.tracker->tracks();
        for (; s.colored < tracks.size(); ++s.colored) {
          const Eigen::Vector2d& p = tracks[s.colored].observations.front().pixel;
          const cv::Vec3b bgr =
              image.at<cv::Vec3b>(std::clamp(static_cast<int>(std::lround(p.y())), 0, image.rows - 1),
                                  std::clamp(static_cast<int>(std::lround(p.x())), 0, image.cols - 1));
          s.colors.push_back({bgr[2], bgr[1], bgr[0]});
        }
        CameraTrackPoints view;
        view.camera = c;
        cv::cvtColor(image, view.gray, cv::COLOR_BGR2GRAY);
        for (size_t t = 0; t < tracks.size(); ++t) {
          if (!tracks[t].active || tracks[t].observations.back().frame != local) continue;
          view.ids.push_back(TrackKey(open[c], static_cast<int>(t)));
          view.pixels.push_back(tracks[t].observations.back().pixel);
          view.bearings.push_back(tracks[t].observations.back().bearing);
        }
        views.push_back(std::move(view));
      }
      for (const auto& m : MatchAcrossCameras(geometry_, views, options_.links, &link_stats_)) {
        out_.cross_camera_links += links_.Union(m.id_a, m.id_b) ? 1 : 0;
        link_records_.push_back({m.id_a, m.id_b, k});
      }
      Progress("tracking", static_cast<int>(read), static_cast<int>(total));
    }
    if (used_.size() < 3)
      throw Error("frames", "only " + std::to_string(used_.size()) +
                                " distinct frame set(s) with images (need at least 3 for structure from motion)");
    out_.tracks_per_camera.assign(cameras, 0);
    long observations = 0, tracks = 0;
    for (const auto& s : segments_) {
      out_.tracks_per_camera[s.camera] += static_cast<int>(s.tracker->tracks().size());
      for (const auto& t : s.tracker->tracks()) observations += t.length();
      tracks += static_cast<long>(s.tracker->tracks().size());
    }
    out_.mean_track_length = tracks > 0 ? static_cast<double>(observations) / static_cast<double>(tracks) : 0.0;
    for (int c = 0; c < cameras; ++c)
      if (out_.tracks_per_camera[c] == 0)
        out_.warnings.push_back("camera " + out_.rig.cameras[c].name +
                                " produced no tracks (black or textureless images): reconstructing without it");
    Stage("tracking", t0, static_cast<int>(tracks),
          "tracks over " + std::to_string(used_.size()) + " frames, mean length " + Fixed(out_.mean_track_length) +
              ", " + std::to_string(out_.cross_camera_links) + " cross-camera links (" +
              std::to_string(link_stats_.ratio_passed) + " ratio, " + std::to_string(link_stats_.cross_checked) +
              " cross-checked, " + std::to_string(link_stats_.epipolar_passed) + " epipolar)");
  }

  // --- trifocal check -------------------------------------------------------------------------

  // Per camera and per three consecutive frames of a tracker, the tensor of the tracks through all
  // three, by RANSAC; a track triple that does not fit marks where the track must be cut. The cut
  // splits the track rather than dropping one observation: a KLT track that fails goes on from
  // where it went wrong (it slid onto another surface at an occlusion edge, or onto a repeated
  // pattern), so everything after the failure follows another scene point, and only a split
  // keeps each piece on one point. A one-frame glitch costs a two-observation piece, which the
  // bundle adjustment's outlier test handles.
  void CheckTrifocal() {
    const auto t0 = Clock::now();
    pieces_.assign(segments_.size(), {});
    TrifocalCheckSummary& sum = out_.trifocal;
    sum.enabled = options_.trifocal;
    // failed[s][t]: the first observations (indices into the track) of its triples that failed.
    std::vector<std::vector<std::vector<int>>> failed(segments_.size());
    std::vector<std::vector<std::vector<char>>> tested(segments_.size());
    const double min_z = std::cos(options_.trifocal_max_angle_deg * M_PI / 180);
    for (size_t s = 0; s < segments_.size(); ++s) {
      const auto& tracks = segments_[s].tracker->tracks();
      failed[s].resize(tracks.size());
      tested[s].resize(tracks.size());
      for (size_t t = 0; t < tracks.size(); ++t) tested[s][t].assign(tracks[t].observations.size(), 0);
      if (!options_.trifocal) continue;
      const double focal = geometry_.focal_px[segments_[s].camera];
      const int frames = segments_[s].tracker->frame_count();
      for (int f = 0; f + 2 < frames; ++f) {
        std::vector<PixelTriple> data;
        std::vector<std::pair<int, int>> where;  // (track, index of its observation of frame f)
        for (int t = 0; t < static_cast<int>(tracks.size()); ++t) {
          const auto& obs = tracks[t].observations;
          const int i = f - obs.front().frame;
          if (i < 0 || i + 2 >= static_cast<int>(obs.size())) continue;
          const Eigen::Vector3d& b1 = obs[i].bearing;
          const Eigen::Vector3d& b2 = obs[i + 1].bearing;
          const Eigen::Vector3d& b3 = obs[i + 2].bearing;
          if (b1.z() < min_z || b2.z() < min_z || b3.z() < min_z) continue;
          PixelTriple d;
          d.triple = {b1.head<2>() / b1.z(), b2.head<2>() / b2.z(), b3.head<2>() / b3.z()};
          // A normalized-plane error e at angle theta from the axis is about e cos^2(theta) as an
          // angle (radially; tangentially e cos(theta)): the residual in pixels of the fisheye.
          const double c = (b1.z() + b2.z() + b3.z()) / 3;
          d.px_per_unit = focal * c * c;
          data.push_back(d);
          where.emplace_back(t, i);
        }
        if (static_cast<int>(data.size()) < options_.trifocal_min_triples) {
          ++sum.triples_unchecked;
          continue;
        }
        RansacOptions ro;
        ro.max_residual = options_.trifocal_threshold_px;
        ro.max_iterations = 500;
        ro.random_seed = static_cast<std::uint64_t>(s * 7919 + f);
        const auto result = Ransac<PixelTrifocalEstimator>(ro).Estimate(data);
        if (!result.success || result.inlier_ratio() < options_.trifocal_min_inlier_ratio) {
          ++sum.triples_unchecked;
          continue;
        }
        ++sum.triples_checked;
        sum.triples_tested += static_cast<long>(data.size());
        for (size_t k = 0; k < data.size(); ++k) {
          auto [t, i] = where[k];
          for (int v = 0; v < 3; ++v) tested[s][t][i + v] = 1;
          if (!result.inlier_mask[k]) {
            failed[s][t].push_back(i);
            ++sum.triples_rejected;
          }
        }
      }
    }
    // Greedy cuts: walking a track, a failed triple that lies wholly inside the current piece
    // starts a new piece at its last observation. A jump between observations j and j + 1 fails
    // the triples starting at j - 1 and j and is cut exactly there.
    for (size_t s = 0; s < segments_.size(); ++s) {
      const auto& tracks = segments_[s].tracker->tracks();
      pieces_[s].resize(tracks.size());
      for (size_t t = 0; t < tracks.size(); ++t) {
        const int n = tracks[t].length();
        sum.tracks_before += 1;
        sum.observations_before += n;
        for (int i = 0; i < n; ++i) sum.untested_observations += tested[s][t][i] ? 0 : 1;
        std::vector<int> starts = {0};
        for (int first : failed[s][t])  // ascending
          if (first >= starts.back()) starts.push_back(first + 2);
        sum.tracks_split += starts.size() > 1 ? 1 : 0;
        starts.push_back(n);
        // A piece of one observation left by a cut cannot be told from the failure itself; a track
        // that was only ever one observation long stays (a cross-camera link may extend it).
        const int min_length = starts.size() > 2 ? 2 : 1;
        for (size_t p = 0; p + 1 < starts.size(); ++p)
          if (starts[p + 1] - starts[p] >= min_length) {
            pieces_[s][t].push_back({starts[p], starts[p + 1]});
            sum.tracks_after += 1;
            sum.observations_after += starts[p + 1] - starts[p];
          }
      }
    }
    sum.seconds = SecondsSince(t0);
    if (!options_.trifocal) return;
    Stage("trifocal", t0, static_cast<int>(sum.observations_after),
          "track observations kept of " + std::to_string(sum.observations_before) + ", " +
              std::to_string(sum.tracks_before) + " tracks -> " + std::to_string(sum.tracks_after) + " (" +
              std::to_string(sum.tracks_split) + " split), " + std::to_string(sum.triples_checked) +
              " frame triples checked, " + std::to_string(sum.triples_unchecked) + " not, " +
              std::to_string(sum.triples_rejected) + " of " + std::to_string(sum.triples_tested) +
              " track triples rejected, " + std::to_string(sum.untested_observations) +
              " observations outside the checked field");
  }

  // Track pieces become points, joined by the cross-camera links of the frame where the link was
  // made; a point with two observations in one camera and frame (a wrong link joined two tracks)
  // loses both of them.
  void BuildPoints() {
    // Piece ids: one per (segment, track, piece), in order.
    std::vector<std::vector<int>> first_piece(segments_.size());
    int next = 0;
    for (size_t s = 0; s < segments_.size(); ++s) {
      first_piece[s].resize(pieces_[s].size());
      for (size_t t = 0; t < pieces_[s].size(); ++t) {
        first_piece[s][t] = next;
        next += static_cast<int>(pieces_[s][t].size());
      }
    }
    // The piece of track `key` that holds its observation of sequence frame k, or -1.
    auto piece_at = [&](long key, int k) {
      const int s = static_cast<int>(key >> 24), t = static_cast<int>(key & 0xffffff);
      const int i = k - segments_[s].first_frame - segments_[s].tracker->tracks()[t].observations.front().frame;
      for (size_t p = 0; p < pieces_[s][t].size(); ++p)
        if (i >= pieces_[s][t][p].first && i < pieces_[s][t][p].second) return first_piece[s][t] + static_cast<int>(p);
      return -1;
    };
    UnionFind links;
    int joined = 0;
    for (const auto& l : link_records_) {
      const int a = piece_at(l.id_a, l.frame), b = piece_at(l.id_b, l.frame);
      if (a >= 0 && b >= 0) joined += links.Union(a, b) ? 1 : 0;
    }
    out_.cross_camera_links = joined;
    std::map<long, int> point_of_root;
    for (int s = 0; s < static_cast<int>(segments_.size()); ++s) {
      const Segment& seg = segments_[s];
      const auto& tracks = seg.tracker->tracks();
      for (int t = 0; t < static_cast<int>(tracks.size()); ++t)
        for (size_t p = 0; p < pieces_[s][t].size(); ++p) {
          const long root = links.Find(first_piece[s][t] + static_cast<int>(p));
          auto [it, inserted] = point_of_root.emplace(root, static_cast<int>(points_.size()));
          if (inserted) {
            points_.emplace_back();
            points_.back().rgb = seg.colors[t];
          }
          MapPoint& mp = points_[it->second];
          for (int i = pieces_[s][t][p].first; i < pieces_[s][t][p].second; ++i) {
            const auto& o = tracks[t].observations[i];
            mp.obs.push_back({seg.first_frame + o.frame, seg.camera, o.pixel, o.bearing, true});
          }
        }
    }
    int conflicts = 0;
    std::vector<MapPoint> kept;
    for (auto& p : points_) {
      std::map<std::pair<int, int>, int> count;
      for (const auto& o : p.obs) ++count[{o.frame, o.camera}];
      std::vector<Obs> clean;
      for (const auto& o : p.obs)
        if (count[{o.frame, o.camera}] == 1) clean.push_back(o);
      conflicts += static_cast<int>(p.obs.size() - clean.size());
      std::set<int> frames;
      for (const auto& o : clean) frames.insert(o.frame);
      if (frames.size() < 2) continue;
      std::sort(clean.begin(), clean.end(), [](const Obs& a, const Obs& b) {
        return a.frame != b.frame ? a.frame < b.frame : a.camera < b.camera;
      });
      p.obs = std::move(clean);
      kept.push_back(std::move(p));
    }
    points_ = std::move(kept);
    // Each frame's observations, in point order: registration, the frames two points share and
    // triangulation look up a frame's points here instead of scanning every point.
    frame_obs_.assign(used_.size(), {});
    for (int i = 0; i < static_cast<int>(points_.size()); ++i)
      for (int k = 0; k < static_cast<int>(points_[i].obs.size()); ++k)
        frame_obs_[points_[i].obs[k].frame].emplace_back(i, k);
    segments_.clear();  // the trackers' images and tracks are no longer needed
    pieces_.clear();
    link_records_.clear();
    if (conflicts > 0)
      Log("points: dropped " + std::to_string(conflicts) + " observations of links that contradict each other");
  }

  // --- initial pair ----------------------------------------------------------------------------

  // The rig's relative pose estimator, or the central one for a camera with one centre.
  RansacReport<Rigid3> RelativePose(const std::vector<RigBearingPair>& pairs, std::uint64_t seed) const {
    RansacOptions ro;
    ro.max_residual = options_.ransac_threshold_px;
    ro.max_iterations = geometry_.central() ? 1000 : 400;
    ro.random_seed = seed;
    if (geometry_.central()) return Ransac<CentralRelativePoseEstimator>(ro, {&geometry_, focal_}).Estimate(pairs);
    return Ransac<RigRelativePoseEstimator>(ro, {&geometry_, focal_}).Estimate(pairs);
  }

  // The points seen in both frames a and b, as bearing pairs (the same camera where it can be), in
  // point order.
  std::vector<RigBearingPair> SharedBearings(int a, int b) const {
    std::unordered_map<int, const Obs*> in_b;
    for (const auto& [i, k] : frame_obs_[b]) in_b.try_emplace(i, &points_[i].obs[k]);
    std::vector<RigBearingPair> pairs;
    int last = -1;
    for (const auto& [i, k] : frame_obs_[a]) {
      if (i == last) continue;  // a's first observation of the point
      last = i;
      auto it = in_b.find(i);
      if (it == in_b.end()) continue;
      const Obs& oa = points_[i].obs[k];
      const Obs* ob = it->second;
      for (const auto& o : points_[i].obs)
        if (o.frame == b && o.camera == oa.camera) ob = &o;
      pairs.push_back({oa.bearing, ob->bearing, oa.camera, ob->camera});
    }
    return pairs;
  }

  // Distinct points a frame sees.
  size_t PointsSeen(int f) const {
    size_t n = 0;
    int last = -1;
    for (const auto& [i, k] : frame_obs_[f]) n += i != last, last = i;
    return n;
  }

  // Frame 0 and every frame whose rays differ from the last key frame's by keyframe_parallax_deg
  // (median, rotation taken out) or that still sees fewer than keyframe_min_shared of its points.
  void SelectKeyFrames() {
    const int frames = static_cast<int>(used_.size());
    keys_ = {0};
    if (!(options_.keyframe_parallax_deg > 0)) {
      for (int f = 1; f < frames; ++f) keys_.push_back(f);
      return;
    }
    int last = 0;
    size_t last_seen = PointsSeen(0);
    for (int f = 1; f < frames; ++f) {
      const std::vector<RigBearingPair> pairs = SharedBearings(last, f);
      bool key = static_cast<double>(pairs.size()) < options_.keyframe_min_shared * static_cast<double>(last_seen);
      if (pairs.size() >= 8) {
        const double parallax = RotationFreeParallaxDeg(pairs);
        if (last == 0) selection_parallax_ = std::max(selection_parallax_, parallax);
        key = key || parallax >= options_.keyframe_parallax_deg;
      }
      if (!key) continue;
      keys_.push_back(f);
      last = f;
      last_seen = PointsSeen(f);
    }
    Log("key frames: " + std::to_string(keys_.size()) + " of " + std::to_string(frames));
  }

  // The first pair (a, b), b - a <= max_init_gap, whose rays differ by enough parallax once the
  // rotation is taken out. The anchor a is frame 0 unless the camera stands still at first (a
  // clip whose first seconds do not move): then it moves on by half the gap until one is found.
  void Initialize() {
    const auto t0 = Clock::now();
    const int frames = static_cast<int>(used_.size());
    world_from_rig_.assign(frames, Rigid3());
    registered_.assign(frames, 0);
    interpolated_.assign(frames, 0);
    double best_parallax = selection_parallax_;
    std::string why = "no later frame shares enough tracked points with frame 0";
    const int anchor_step = std::max(1, options_.max_init_gap / 2);
    const int keys = static_cast<int>(keys_.size());
    for (int ka = 0; ka + 1 < keys && init_frame_ < 0; ka += anchor_step) {
      const int a = keys_[ka];
      const InitialPair tried = TryInitialPair(ka, &best_parallax, &why);
      if (tried.frame >= 0) {
        anchor_ = a;
        init_frame_ = tried.frame;
        registration_order_ = {a, tried.frame};
        world_from_rig_[tried.frame] = tried.pose;
        registered_[a] = registered_[tried.frame] = 1;
      }
      if (!geometry_.central()) break;  // the rig keeps its frame-0 anchor and its messages
    }
    if (init_frame_ < 0) {
      if (best_parallax < options_.min_init_parallax_deg && geometry_.central()) {
        StandStill(best_parallax);
        return;
      }
      if (best_parallax > 0 && best_parallax < options_.min_init_parallax_deg)
        throw Error("reconstruct", "the rig does not move enough to triangulate: the median parallax between frame " +
                                       std::to_string(used_[0].index) + " and the next " +
                                       std::to_string(std::min(frames - 1, options_.max_init_gap)) +
                                       " frames is at most " + Fixed(best_parallax, 3) + " deg (need " +
                                       Fixed(options_.min_init_parallax_deg) +
                                       "): a static camera or a pure rotation has no depth");
      throw Error("reconstruct", "no initial frame pair: " + why);
    }
    TriangulateNew(options_.min_triangulation_angle_deg);
    BundleAdjust(30);
    RemoveOutliers();
    ApplyRoadScale("initialization");
    TriangulateNew(options_.min_triangulation_angle_deg);
    Stage("initialization", t0, init_inliers_,
          "relative-pose inliers between frames " + std::to_string(used_[anchor_].index) + " and " +
              std::to_string(used_[init_frame_].index) + ", " + std::to_string(CountTriangulated()) +
              " points triangulated");
  }

  struct InitialPair {
    int frame = -1;
    Rigid3 pose;  // anchor_from_frame
  };

  // Key frame ka against the next max_init_gap key frames.
  InitialPair TryInitialPair(int ka, double* best_parallax, std::string* why) {
    const int keys = static_cast<int>(keys_.size());
    const int a = keys_[ka];
    for (int kj = ka + 1; kj < keys && kj <= ka + options_.max_init_gap; ++kj) {
      const int j = keys_[kj];
      const std::vector<RigBearingPair> pairs = SharedBearings(a, j);
      const std::string names = "frames " + std::to_string(used_[a].index) + " and " + std::to_string(used_[j].index);
      if (static_cast<int>(pairs.size()) < options_.min_init_inliers) {
        *why = names + " share only " + std::to_string(pairs.size()) + " tracked points (need " +
               std::to_string(options_.min_init_inliers) + ")";
        break;  // later frames share even fewer
      }
      // Parallax with the rotation taken out, measured before any translation is estimated: the
      // best rotation between the two frames' rig-frame rays (Wahba's problem, SVD) and the median
      // angle left over. A static rig or a pure rotation leaves only noise, and a solver's
      // translation would then be noise too.
      // The best parallax seen: Wahba's below the threshold, else the pose's own (below).
      const double rotation_free = RotationFreeParallaxDeg(pairs);
      if (rotation_free < options_.min_init_parallax_deg) {
        *best_parallax = std::max(*best_parallax, rotation_free);
        Log("initialization: " + names + ": median parallax after rotation " + Fixed(rotation_free, 3) +
            " deg, too little");
        continue;
      }
      const auto result = RelativePose(pairs, static_cast<std::uint64_t>(j));
      if (!result.success || result.num_inliers < options_.min_init_inliers) {
        *why = names + ": relative pose " + result.BriefReport();
        *best_parallax = std::max(*best_parallax, rotation_free);
        continue;
      }
      std::vector<double> parallax;
      for (size_t i = 0; i < pairs.size(); ++i) {
        if (!result.inlier_mask[i]) continue;
        const Eigen::Vector3d d1 = geometry_.rig_from_cam[pairs[i].camera1].rotation * pairs[i].bearing1;
        const Eigen::Vector3d d2 =
            result.model.rotation * geometry_.rig_from_cam[pairs[i].camera2].rotation * pairs[i].bearing2;
        parallax.push_back(AngleBetween(d1, d2) * 180 / M_PI);
      }
      std::nth_element(parallax.begin(), parallax.begin() + parallax.size() / 2, parallax.end());
      const double median = parallax[parallax.size() / 2];
      Log("initialization: " + names + ": " + result.BriefReport() + ", median parallax " + Fixed(median, 3) + " deg");
      *best_parallax = std::max(*best_parallax, median);
      if (median < options_.min_init_parallax_deg) continue;
      Rigid3 pose = result.model;  // rig_a_from_rig_j
      const double length = pose.translation.norm();
      if (!(length > 1e-9) || !pose.AllFinite()) continue;
      // The 17-point solver's translation length rests on the 8 cm camera offsets alone (a central
      // camera's is 1): keep it only as a starting unit, the road fixes the scale below.
      if (length < 1e-3 || length > 1e3) pose.translation /= length;
      init_inliers_ = result.num_inliers;
      return {j, pose};
    }
    return {};
  }

  // The rotation between two frames' rig-frame rays (d1 ~ r d2), by Wahba's problem fitted again
  // without the quarter of the rays it fits worst: moving things (a car, waves, the operator)
  // pull a least-squares rotation off, and their rays would then read as parallax.
  Eigen::Matrix3d RobustRotation(const std::vector<Eigen::Vector3d>& d1, const std::vector<Eigen::Vector3d>& d2) const {
    Eigen::Matrix3d r = BestRotation(d1, d2);
    if (d1.size() < 8) return r;
    std::vector<std::pair<double, size_t>> errors;
    for (size_t i = 0; i < d1.size(); ++i) errors.emplace_back(AngleBetween(d1[i], r * d2[i]), i);
    std::sort(errors.begin(), errors.end());
    std::vector<Eigen::Vector3d> k1, k2;
    for (size_t i = 0; i < errors.size() * 3 / 4; ++i) {
      k1.push_back(d1[errors[i].second]);
      k2.push_back(d2[errors[i].second]);
    }
    return BestRotation(k1, k2);
  }

  double RotationFreeParallaxDeg(const std::vector<RigBearingPair>& pairs) const {
    std::vector<Eigen::Vector3d> d1, d2;
    for (const auto& p : pairs) {
      d1.push_back(geometry_.rig_from_cam[p.camera1].rotation * p.bearing1);
      d2.push_back(geometry_.rig_from_cam[p.camera2].rotation * p.bearing2);
    }
    const Eigen::Matrix3d r = RobustRotation(d1, d2);
    std::vector<double> angles;
    for (size_t i = 0; i < d1.size(); ++i) angles.push_back(AngleBetween(d1[i], r * d2[i]) * 180 / M_PI);
    std::nth_element(angles.begin(), angles.begin() + angles.size() / 2, angles.end());
    return angles[angles.size() / 2];
  }

  // A central camera that never moves enough to triangulate (a tripod, a pure rotation) still
  // gets a pose for every frame, so that a car can stand in its scene: one position, and the
  // rotation from frame to frame by Wahba's problem over the tracks they share (RobustRotation).
  void StandStill(double best_parallax) {
    const int frames = static_cast<int>(used_.size());
    out_.warnings.push_back("the camera does not move enough to triangulate (median parallax at most " +
                            Fixed(best_parallax, 3) +
                            " deg): a tripod or a pure rotation; every frame stands at one "
                            "position and only its rotation is tracked");
    standing_still_ = true;
    for (int f = 0; f < frames; ++f) registered_[f] = 1;
    // Each frame against the earliest of f-1, f-2, f-4, ... that still shares enough tracks with
    // it: chaining every frame to the one before adds each step's error to the next.
    constexpr size_t kEnoughShared = 30;
    for (int f = 1; f < frames; ++f) {
      int base = f - 1;
      std::vector<RigBearingPair> pairs = SharedBearings(base, f);
      for (int back = 2; f - back >= 0; back *= 2) {
        std::vector<RigBearingPair> farther = SharedBearings(f - back, f);
        if (farther.size() < kEnoughShared) break;
        base = f - back;
        pairs = std::move(farther);
      }
      Eigen::Matrix3d r = Eigen::Matrix3d::Identity();  // rig_base_from_rig_f
      if (pairs.size() >= 3) {
        std::vector<Eigen::Vector3d> d1, d2;
        for (const auto& p : pairs) {
          const Eigen::Vector3d a = geometry_.rig_from_cam[p.camera1].rotation * p.bearing1;
          const Eigen::Vector3d b = geometry_.rig_from_cam[p.camera2].rotation * p.bearing2;
          d1.push_back(a);
          d2.push_back(b);
        }
        r = RobustRotation(d1, d2);
      }
      world_from_rig_[f].rotation = world_from_rig_[base].rotation * r;
    }
  }

  // --- registration ----------------------------------------------------------------------------

  // The key frames, outwards from the initial pair: those between it, before the anchor, after it.
  void RegisterAll() {
    const auto t0 = Clock::now();
    if (standing_still_) return;
    const int keys = static_cast<int>(keys_.size());
    const int ka = static_cast<int>(std::find(keys_.begin(), keys_.end(), anchor_) - keys_.begin());
    const int kj = static_cast<int>(std::find(keys_.begin(), keys_.end(), init_frame_) - keys_.begin());
    std::vector<int> order;
    for (int k = kj - 1; k > ka; --k) order.push_back(keys_[k]);
    for (int k = ka - 1; k >= 0; --k) order.push_back(keys_[k]);
    for (int k = kj + 1; k < keys; ++k) order.push_back(keys_[k]);
    int since_bundle = 0, done = 2, inliers = 0;
    for (int f : order) {
      inliers += Register(f);
      registration_order_.push_back(f);
      TriangulateNew(options_.min_triangulation_angle_deg, f);
      ++done;
      Progress("registration", done, keys);
      if (++since_bundle >= options_.bundle_every) {
        BundleAdjust(20, /*window=*/true);
        RemoveOutliers();
        if (!metric_) ApplyRoadScale("registration");
        since_bundle = 0;
      }
    }
    Stage("registration", t0, inliers,
          "2D-3D inliers over " + std::to_string(order.size()) + " registered key frames of " +
              std::to_string(used_.size()) + ", " + std::to_string(CountTriangulated()) + " points");
  }

  // The frames between key frames, against the finished map; one that cannot be registered takes
  // the pose interpolated between the registered frames around it (rotation by slerp, position
  // linearly, by time).
  void RegisterBetweenKeyFrames() {
    const int frames = static_cast<int>(used_.size());
    if (static_cast<int>(keys_.size()) == frames || standing_still_) return;
    const auto t0 = Clock::now();
    std::vector<int> failed;
    int inliers = 0;
    std::string why;
    for (int f = 0; f < frames; ++f) {
      if (registered_[f]) continue;
      try {
        inliers += Register(f);
      } catch (const Error& e) {
        if (why.empty()) why = e.what();
        failed.push_back(f);
      }
    }
    for (int f : failed) {
      int before = f - 1, after = f + 1;
      while (before >= 0 && !registered_[before]) --before;
      while (after < frames && !registered_[after]) ++after;
      world_from_rig_[f] = before < 0 ? world_from_rig_[after]
                           : after >= frames
                               ? world_from_rig_[before]
                               : Interpolate(world_from_rig_[before], world_from_rig_[after],
                                             Fraction(used_[before], used_[f], used_[after], before, f, after));
      interpolated_[f] = 1;
    }
    for (int f : failed) registered_[f] = 1;
    if (!failed.empty())
      out_.warnings.push_back(std::to_string(failed.size()) + " frame(s) between key frames could not be registered (" +
                              why + "): their poses are interpolated between the frames around them");
    Stage("frames between key frames", t0, inliers,
          "2D-3D inliers over " +
              std::to_string(frames - static_cast<int>(keys_.size()) - static_cast<int>(failed.size())) +
              " frames registered against the map, " + std::to_string(failed.size()) + " interpolated");
  }

  // Where f lies between frames a and b: by timestamp when they differ, else by frame number.
  static double Fraction(const UsedFrame& a, const UsedFrame& f, const UsedFrame& b, int ia, int i, int ib) {
    if (b.timestamp > a.timestamp)
      return std::clamp((f.timestamp - a.timestamp) / (b.timestamp - a.timestamp), 0.0, 1.0);
    return static_cast<double>(i - ia) / static_cast<double>(ib - ia);
  }

  static Rigid3 Interpolate(const Rigid3& a, const Rigid3& b, double t) {
    Rigid3 r;
    r.rotation = Eigen::Quaterniond(a.rotation).slerp(t, Eigen::Quaterniond(b.rotation)).toRotationMatrix();
    r.translation = (1 - t) * a.translation + t * b.translation;
    return r;
  }

  int Register(int f) {
    std::vector<RigBearingPoint> data;
    std::vector<std::pair<int, int>> where;  // (point, observation)
    for (const auto& [i, k] : frame_obs_[f]) {
      const MapPoint& p = points_[i];
      if (!p.triangulated) continue;
      data.push_back({p.obs[k].bearing, p.obs[k].camera, p.x});
      where.emplace_back(i, k);
    }
    const std::string frame_name = "frame " + std::to_string(used_[f].index);
    if (static_cast<int>(data.size()) < options_.min_pose_inliers)
      throw Error(frame_name, "cannot be registered: only " + std::to_string(data.size()) +
                                  " tracked points with a 3D position are visible (need " +
                                  std::to_string(options_.min_pose_inliers) +
                                  "); the tracks broke off (a textureless stretch, a cut or black images?)");
    RansacOptions ro;
    ro.max_residual = options_.ransac_threshold_px;
    ro.max_iterations = 1000;
    ro.random_seed = static_cast<std::uint64_t>(f);
    const bool central = geometry_.central();
    const auto result = central ? Ransac<CentralAbsolutePoseEstimator>(ro, {&geometry_, focal_}).Estimate(data)
                                : Ransac<RigAbsolutePoseEstimator>(ro, {&geometry_, focal_}).Estimate(data);
    if (!result.success || result.num_inliers < options_.min_pose_inliers)
      throw Error(frame_name, "cannot be registered: " + std::to_string(result.num_inliers) + " of " +
                                  std::to_string(data.size()) + " 2D-3D matches agree on a pose (need " +
                                  std::to_string(options_.min_pose_inliers) + ")");
    std::vector<RigBearingPoint> inliers;
    for (size_t i = 0; i < data.size(); ++i)
      if (result.inlier_mask[i]) inliers.push_back(data[i]);
    Rigid3 pose = central ? RefineCentralAbsolutePose(geometry_, inliers, result.model)
                          : RefineAbsolutePose(geometry_, inliers, result.model);
    if (!pose.AllFinite()) throw Error(frame_name, "the pose estimate is not finite");
    world_from_rig_[f] = pose;
    registered_[f] = 1;
    std::vector<double> residuals;
    RigAbsolutePoseEstimator{&geometry_, focal_}.Residuals(data, pose, &residuals);
    int agreeing = 0;
    for (size_t i = 0; i < data.size(); ++i) {
      const bool ok = residuals[i] <= options_.ransac_threshold_px;
      points_[where[i].first].obs[where[i].second].inlier = ok;
      agreeing += ok;
    }
    return agreeing;
  }

  // Points with no position yet and inlier observations in two or more registered frames; with
  // `frame` >= 0 only the points that frame sees (the only ones its registration can complete),
  // unless a bundle adjustment since the last call moved the poses (a point that failed may pass
  // now) or an outlier removal took positions away.
  void TriangulateNew(double min_angle_deg, int frame = -1) {
    auto consider = [&](MapPoint& p) {
      if (!p.triangulated) TriangulatePoint(min_angle_deg, &p);
    };
    if (frame < 0 || retry_all_points_) {
      for (auto& p : points_) consider(p);
      retry_all_points_ = false;
      return;
    }
    int last = -1;
    for (const auto& [i, k] : frame_obs_[frame]) {
      if (i != last) consider(points_[i]);
      last = i;
    }
  }

  void TriangulatePoint(double min_angle_deg, MapPoint* point) const {
    MapPoint& p = *point;
    std::vector<Eigen::Vector3d> bearings;
    std::vector<CamFromWorld> poses;
    std::set<int> frames;
    for (const auto& o : p.obs) {
      if (!registered_[o.frame] || !o.inlier) continue;
      bearings.push_back(o.bearing);
      poses.push_back(CamPose(geometry_, world_from_rig_[o.frame], o.camera));
      frames.insert(o.frame);
    }
    if (frames.size() < 2) return;
    TriangulatedPoint t;
    if (!TriangulateDlt(bearings, poses, &t)) return;
    if (!t.in_front || t.parallax_deg < min_angle_deg ||
        t.max_angular_error_rad * focal_ > options_.ransac_threshold_px)
      return;
    p.x = t.point;
    p.triangulated = true;
  }

  int CountTriangulated() const {
    int n = 0;
    for (const auto& p : points_) n += p.triangulated;
    return n;
  }

  // --- bundle adjustment, outliers, scale ---------------------------------------------------------

  // With `window`, only the last bundle_window registered key frames move, with the points they
  // see; the frames before hold the gauge and the scale.
  BundleAdjustmentReport BundleAdjust(int max_iterations, bool window = false) {
    BundleAdjustmentProblem problem;
    problem.rig = geometry_;
    problem.world_from_rig = world_from_rig_;
    problem.pose_constant.assign(world_from_rig_.size(), 0);
    problem.pose_constant[static_cast<size_t>(anchor_)] = 1;
    const int held = static_cast<int>(registration_order_.size()) - options_.bundle_window;
    window = window && options_.bundle_window > 0 && held >= 2;
    std::vector<char> seen(window ? points_.size() : 0, 0);
    if (window) {
      for (int k = 0; k < held; ++k) problem.pose_constant[static_cast<size_t>(registration_order_[k])] = 1;
      for (size_t k = static_cast<size_t>(held); k < registration_order_.size(); ++k)
        for (const auto& [i, o] : frame_obs_[registration_order_[k]]) seen[i] = 1;
    }
    std::vector<int> index_of(points_.size(), -1);
    for (int i = 0; i < static_cast<int>(points_.size()); ++i) {
      const MapPoint& p = points_[i];
      if (!p.triangulated || (window && !seen[i])) continue;
      for (const auto& o : p.obs) {
        if (!registered_[o.frame] || !o.inlier) continue;
        if (index_of[i] < 0) {
          index_of[i] = static_cast<int>(problem.points.size());
          problem.points.push_back(p.x);
        }
        problem.observations.push_back({o.frame, o.camera, index_of[i], o.bearing});
      }
    }
    if (!window && (metric_ || geometry_.central())) {
      // The registered frame farthest from the anchor keeps its distance: the scale the road gave
      // or, for a central camera (whose offsets fix no scale), the initial pair's unit.
      int far = -1;
      double distance = 0;
      for (size_t f = 0; f < world_from_rig_.size(); ++f) {
        const double d = (world_from_rig_[f].translation - world_from_rig_[anchor_].translation).norm();
        if (registered_[f] && d > distance) distance = d, far = static_cast<int>(f);
      }
      if (far >= 0 && distance > 0) {
        problem.scale_prior.enabled = true;
        problem.scale_prior.frame_a = anchor_;
        problem.scale_prior.frame_b = far;
        problem.scale_prior.distance = distance;
        problem.scale_prior.sigma = 1e-4 * distance;
      }
    }
    BundleAdjustmentOptions ba = options_.bundle;
    ba.max_iterations = std::min(ba.max_iterations, max_iterations);
    const BundleAdjustmentReport report = AdjustBundle(ba, &problem);
    if (!report.converged) throw Error("bundle adjustment", "no usable solution (" + report.message + ")");
    for (size_t f = 0; f < world_from_rig_.size(); ++f)
      if (registered_[f]) {
        if (!problem.world_from_rig[f].AllFinite())
          throw Error("bundle adjustment", "the pose of frame " + std::to_string(used_[f].index) + " is not finite");
        world_from_rig_[f] = problem.world_from_rig[f];
      }
    for (size_t i = 0; i < points_.size(); ++i)
      if (index_of[i] >= 0) points_[i].x = problem.points[index_of[i]];
    last_bundle_ = report;
    retry_all_points_ = true;
    Log("bundle adjustment: " + std::to_string(problem.observations.size()) + " observations, " +
        std::to_string(problem.points.size()) + " points, RMSE " + Fixed(report.initial_rmse_px, 3) + " -> " +
        Fixed(report.final_rmse_px, 3) + " px in " + std::to_string(report.iterations) + " iterations, " +
        Fixed(report.seconds) + " s");
    return report;
  }

  // Observations whose bearing error exceeds max_reprojection_px become outliers; a point left
  // with fewer than two frames loses its position (it may come back by triangulation).
  int RemoveOutliers() {
    int removed = 0;
    for (auto& p : points_) {
      if (!p.triangulated) continue;
      std::set<int> frames;
      for (auto& o : p.obs) {
        if (!registered_[o.frame] || !o.inlier) continue;
        const Eigen::Vector3d in_cam = CamPose(geometry_, world_from_rig_[o.frame], o.camera) * p.x;
        const double err = in_cam.dot(o.bearing) > 0 ? AngleBetween(in_cam, o.bearing) * geometry_.focal_px[o.camera]
                                                     : std::numeric_limits<double>::infinity();
        if (!(err <= options_.max_reprojection_px)) {
          o.inlier = false;
          ++removed;
        } else {
          frames.insert(o.frame);
        }
      }
      if (frames.size() < 2 || !p.x.allFinite()) {
        p.triangulated = false;
        retry_all_points_ = true;
      }
    }
    return removed;
  }

  std::vector<Rigid3> RegisteredPoses() const {
    std::vector<Rigid3> poses;
    for (size_t f = 0; f < world_from_rig_.size(); ++f)
      if (registered_[f]) poses.push_back(world_from_rig_[f]);
    return poses;
  }

  std::vector<Eigen::Vector3d> TriangulatedPoints() const {
    std::vector<Eigen::Vector3d> xs;
    for (const auto& p : points_)
      if (p.triangulated) xs.push_back(p.x);
    return xs;
  }

  // Scales the world about frame 0's rig (which stays fixed) so the rig stands at its height.
  void ApplyRoadScale(const std::string& when) {
    if (!(out_.rig_height_m > 0)) return;
    const RoadPlane plane = FitRoadPlane(TriangulatedPoints(), RegisteredPoses(), out_.rig_height_m, options_.road);
    Log("road plane (" + when + "): " + plane.message);
    if (!plane.found) return;
    const double s = plane.scale;
    for (auto& pose : world_from_rig_) pose.translation *= s;
    for (auto& p : points_) p.x *= s;
    out_.scale_applied *= s;
    metric_ = true;
  }

  // --- final stages ----------------------------------------------------------------------------

  void Finish() {
    auto t0 = Clock::now();
    if (standing_still_) {
      PlaceStandingCamera();
      Stage("metric scale", t0, 0, "no motion: the camera placed " + Fixed(out_.road.rig_height) + " above z = 0");
      t0 = Clock::now();
      Export();
      Stage("export", t0, 0, "points");
      return;
    }
    BundleAdjust(options_.bundle.max_iterations);
    int removed = RemoveOutliers();
    TriangulateNew(options_.min_triangulation_angle_deg);
    BundleAdjust(options_.bundle.max_iterations);
    removed += RemoveOutliers();
    Stage("bundle adjustment", t0, CountInlierObservations(),
          "inlier observations after " + std::to_string(removed) + " outliers removed, RMSE " +
              Fixed(last_bundle_.final_rmse_px, 3) + " px (bearing)");
    RegisterBetweenKeyFrames();

    t0 = Clock::now();
    if (!(out_.rig_height_m > 0)) {
      out_.warnings.push_back(out_.rig.path.empty()
                                  ? "no camera height given: the trajectory is up to scale (not metres)"
                                  : "the rig file gives no rig_height_m: the reconstruction keeps an arbitrary scale");
    } else {
      ApplyRoadScale("after bundle adjustment");
      if (!metric_) {
        out_.warnings.push_back("no road plane found below the rig: the scale is not metric");
      } else if (!geometry_.central()) {
        // The camera offsets are metric: the rescaled world is adjusted once more so they agree,
        // holding the scale where the road put it.
        BundleAdjust(options_.bundle.max_iterations);
        RemoveOutliers();
        ApplyRoadScale("final");
      }
    }
    AlignToRoad();
    Stage("metric scale", t0, out_.road.inliers, "road-plane inliers, " + out_.road.message);

    t0 = Clock::now();
    Export();
    Stage("export", t0, static_cast<int>(out_.points.size()), "points");
  }

  int CountInlierObservations() const {
    int n = 0;
    for (const auto& p : points_)
      if (p.triangulated)
        for (const auto& o : p.obs) n += registered_[o.frame] && o.inlier;
    return n;
  }

  // The output world: road plane z = 0, z up, origin below frame 0's rig, x along its heading.
  void AlignToRoad() {
    const RoadPlane plane = FitRoadPlane(TriangulatedPoints(), RegisteredPoses(), out_.rig_height_m, options_.road);
    Eigen::Vector3d n = plane.found ? plane.normal : world_from_rig_[0].rotation.col(2);
    const Eigen::Vector3d c0 = world_from_rig_[0].translation;
    const double height = plane.found ? plane.Distance(c0) : 0.0;
    Eigen::Vector3d x = world_from_rig_[0].rotation.col(0);
    x = (x - x.dot(n) * n).normalized();
    Rigid3 new_from_old;
    new_from_old.rotation.row(0) = x.transpose();
    new_from_old.rotation.row(1) = n.cross(x).transpose();
    new_from_old.rotation.row(2) = n.transpose();
    new_from_old.translation = -(new_from_old.rotation * (c0 - height * n));
    for (auto& pose : world_from_rig_) pose = new_from_old * pose;
    for (auto& p : points_) p.x = new_from_old * p.x;
    out_.road = FitRoadPlane(TriangulatedPoints(), RegisteredPoses(), out_.rig_height_m, options_.road);
  }

  // A camera that never moved: the world's z axis is frame 0's up, the road is z = 0 and the
  // camera stands at its height above it (the given height, else 1 unit, said in a warning).
  void PlaceStandingCamera() {
    const bool metric = out_.rig_height_m > 0;
    const double height = metric ? out_.rig_height_m : 1.0;
    if (!metric) out_.warnings.push_back("no camera height given: the camera stands 1 unit above the road");
    const Eigen::Matrix3d new_from_old = world_from_rig_[0].rotation.transpose();
    for (auto& pose : world_from_rig_) {
      pose.rotation = new_from_old * pose.rotation;
      pose.translation = Eigen::Vector3d(0, 0, height);
    }
    out_.road = RoadPlane();
    out_.road.rig_height = height;
    out_.road.message = "no road plane measured (the camera does not move); the road is assumed " + Fixed(height) +
                        (metric ? " m" : " units") + " below the camera";
    out_.scale_source = metric ? out_.scale_source : "";
  }

  void Export() {
    // Output frames: the used ones in order, with duplicates re-inserted after their original.
    std::vector<int> out_of_used(used_.size());
    size_t d = 0;
    for (int k = 0; k < static_cast<int>(used_.size()); ++k) {
      ReconstructedFrame f;
      f.index = used_[k].index;
      f.timestamp = used_[k].timestamp;
      f.world_from_rig = world_from_rig_[k];
      f.key = standing_still_ || std::binary_search(keys_.begin(), keys_.end(), k);
      f.interpolated = interpolated_[k] != 0;
      out_of_used[k] = static_cast<int>(out_.frames.size());
      out_.frames.push_back(f);
      for (; d < duplicates_.size() && duplicates_[d].duplicate_of == k; ++d) {
        ReconstructedFrame dup = f;
        dup.index = duplicates_[d].index;
        dup.timestamp = duplicates_[d].timestamp;
        dup.duplicate_of = out_of_used[k];
        out_.frames.push_back(dup);
      }
    }
    double sq = 0;
    int n = 0;
    auto& contributions = out_.camera_contributions;
    contributions.assign(geometry_.camera_count(), {});
    for (const auto& p : points_) {
      for (const auto& o : p.obs) ++contributions[o.camera].observations;
      if (!p.triangulated) continue;
      ReconstructedPoint rp;
      rp.position = p.x;
      rp.rgb = p.rgb;
      double psq = 0;
      for (const auto& o : p.obs) {
        if (!registered_[o.frame] || !o.inlier) continue;
        const auto& cam = out_.rig.cameras[o.camera];
        const Eigen::Vector3d in_cam = CamPose(geometry_, world_from_rig_[o.frame], o.camera) * p.x;
        Eigen::Vector2d pixel;
        if (!cam.model.Project(in_cam, &pixel)) continue;
        Eigen::Vector2d residual = pixel - o.pixel;
        // An equirect image's columns wrap: an observation at the seam may project onto the other side.
        if (cam.model.type() == capture::CameraModelType::kEquirectangular)
          residual.x() = std::remainder(residual.x(), static_cast<double>(cam.model.width()));
        const double e2 = residual.squaredNorm();
        psq += e2;
        sq += e2;
        ++n;
        rp.observations.push_back({out_of_used[o.frame], o.camera, o.pixel, o.bearing});
        ++out_.frames[out_of_used[o.frame]].inliers;
      }
      if (rp.observations.size() < 2) continue;
      for (const auto& o : rp.observations) ++contributions[o.camera].inliers;
      rp.error_px = std::sqrt(psq / static_cast<double>(rp.observations.size()));
      out_.points.push_back(std::move(rp));
    }
    out_.observations = n;
    out_.rmse_px = n > 0 ? std::sqrt(sq / n) : 0.0;
    WarnAboutRejectedCameras();
    for (const auto& f : out_.frames)
      if (!f.world_from_rig.AllFinite())
        throw Error("reconstruct", "frame " + std::to_string(f.index) + " ended with a non-finite pose");
  }

  // A camera that keeps a far smaller share of its observations than the best camera of the rig
  // saw something that does not move with the rig. On street_a the cameras keep 57-85 % of
  // theirs (6 to 40 frames, trifocal check on or off); one playing its frames backwards keeps 4 %.
  void WarnAboutRejectedCameras() {
    auto& contributions = out_.camera_contributions;
    double best = 0;
    for (auto& c : contributions) {
      c.rejected = c.observations - c.inliers;
      if (c.observations > 0)
        best = std::max(best, static_cast<double>(c.inliers) / static_cast<double>(c.observations));
    }
    for (size_t c = 0; c < contributions.size(); ++c) {
      const auto& k = contributions[c];
      if (k.observations == 0) continue;
      const double share = static_cast<double>(k.inliers) / static_cast<double>(k.observations);
      if (share < kRejectedCameraShare * best)
        out_.warnings.push_back("camera " + out_.rig.cameras[c].name + ": " + std::to_string(k.rejected) + " of " +
                                std::to_string(k.observations) + " observations rejected (" +
                                Fixed(100 * (1 - share), 1) + " %, the best camera keeps " + Fixed(100 * best, 1) +
                                " %): its tracks disagree with the rig's motion (another camera's or another time's "
                                "images, or wrong extrinsics?); the other cameras carry the poses");
    }
  }
  static constexpr double kRejectedCameraShare = 0.25;

  ReconstructionOptions options_;
  ReconstructionCallbacks callbacks_;
  RigGeometry geometry_;
  double focal_ = 1;
  Reconstruction out_;
  std::vector<Segment> segments_;
  UnionFind links_;  // of whole tracks: counts the links while tracking
  struct LinkRecord {
    long id_a = 0, id_b = 0;
    int frame = 0;  // sequence frame where the two tracks matched
  };
  std::vector<LinkRecord> link_records_;
  // pieces_[segment][track]: [first, end) observation ranges that survived the trifocal check.
  std::vector<std::vector<std::vector<std::pair<int, int>>>> pieces_;
  CrossCameraStats link_stats_;
  std::vector<UsedFrame> used_;
  std::vector<UsedFrame> duplicates_;  // duplicate_of: index into used_
  std::vector<MapPoint> points_;
  std::vector<Rigid3> world_from_rig_;
  std::vector<char> registered_;
  std::vector<char> interpolated_;  // posed by interpolation between key frames
  // frame_obs_[f]: (point, observation) of every observation of frame f, in point order.
  std::vector<std::vector<std::pair<int, int>>> frame_obs_;
  std::vector<int> keys_;                // key frames, ascending
  double selection_parallax_ = 0;        // the largest parallax against frame 0 seen choosing them
  std::vector<int> registration_order_;  // key frames as they were registered: the window's order
  bool retry_all_points_ = false;        // poses moved or positions were removed: retry every point
  int init_inliers_ = 0;
  int anchor_ = 0;               // the initial pair's first frame: the world's origin until AlignToRoad
  int init_frame_ = -1;          // its second
  bool standing_still_ = false;  // a central camera that never moved: rotations only
  BundleAdjustmentReport last_bundle_;
  bool metric_ = false;  // a road scale was applied; bundle adjustments then hold the scale
};

}  // namespace

void ReconstructionOptions::Check() const {
  klt.Check();
  links.Check();
  bundle.Check();
  road.Check();
  if (!(rig_height_m >= 0)) throw Error("rig_height_m", "must be >= 0");
  if (max_frames < 0) throw Error("max_frames", "must be >= 0");
  if (!(ransac_threshold_px > 0)) throw Error("ransac_threshold_px", "must be > 0");
  if (min_init_inliers < RigRelativePoseEstimator::kMinimalSample)
    throw Error("min_init_inliers", "must be >= " + std::to_string(RigRelativePoseEstimator::kMinimalSample));
  if (!(min_init_parallax_deg > 0)) throw Error("min_init_parallax_deg", "must be > 0");
  if (max_init_gap < 1) throw Error("max_init_gap", "must be >= 1");
  if (min_pose_inliers < 6) throw Error("min_pose_inliers", "must be >= 6");
  if (!(min_triangulation_angle_deg > 0)) throw Error("min_triangulation_angle_deg", "must be > 0");
  if (!(max_reprojection_px > 0)) throw Error("max_reprojection_px", "must be > 0");
  if (bundle_every < 1) throw Error("bundle_every", "must be >= 1");
  if (bundle_window < 0) throw Error("bundle_window", "must be >= 0");
  if (!(keyframe_parallax_deg >= 0)) throw Error("keyframe_parallax_deg", "must be >= 0");
  if (!(keyframe_min_shared >= 0 && keyframe_min_shared <= 1)) throw Error("keyframe_min_shared", "must be in [0, 1]");
  if (chunk_overlap < 3) throw Error("chunk_overlap", "must be >= 3 (frames shared by two chunks)");
  if (chunk_frames != 0 && chunk_frames < 4L * chunk_overlap)
    throw Error("chunk_frames", "must be 0 (one piece) or at least 4 x chunk_overlap");
  if (!(trifocal_threshold_px > 0)) throw Error("trifocal_threshold_px", "must be > 0");
  if (!(trifocal_max_angle_deg > 0 && trifocal_max_angle_deg < 90))
    throw Error("trifocal_max_angle_deg", "must be in (0, 90): the virtual pinhole sees less than a hemisphere");
  if (trifocal_min_triples < TrifocalEstimator::kMinimalSample)
    throw Error("trifocal_min_triples", "must be >= " + std::to_string(TrifocalEstimator::kMinimalSample));
  if (!(trifocal_min_inlier_ratio >= 0 && trifocal_min_inlier_ratio <= 1))
    throw Error("trifocal_min_inlier_ratio", "must be in [0, 1]");
}

ReconstructionOptions OneCameraReconstructionOptions() {
  ReconstructionOptions o;
  o.klt.quality_level = 0.001;
  return o;
}

Reconstruction Reconstruct(const capture::Rig& rig, capture::Source& source, const ReconstructionOptions& options,
                           const ReconstructionCallbacks& callbacks) {
  options.Check();
  if (options.chunk_frames == 0) return Reconstructor(rig, options, callbacks).Run(source);
  ReconstructionOptions piece_options = options;
  piece_options.max_frames = 0;  // each chunk's source ends where the chunk does
  return ReconstructInChunks(source, options, callbacks,
                             [&](capture::Source& chunk, const ReconstructionCallbacks& chunk_callbacks) {
                               return Reconstructor(rig, piece_options, chunk_callbacks).Run(chunk);
                             });
}

}  // namespace odvr::tracking
