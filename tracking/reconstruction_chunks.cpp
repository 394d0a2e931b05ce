#include "tracking/reconstruction_chunks.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/timing.h"

namespace odvr::tracking {
namespace {

// The next chunk's frame sets: first those kept from the chunk before (and one read ahead), then
// fresh ones from the clip up to `limit`; it keeps the last `overlap` sets it delivered.
class ChunkSource : public capture::Source {
 public:
  ChunkSource(capture::Source& clip, std::deque<capture::FrameSet> replay, long limit, size_t overlap)
      : clip_(clip), replay_(std::move(replay)), limit_(limit), overlap_(overlap) {}

  int camera_count() const override { return clip_.camera_count(); }
  std::string description() const override { return clip_.description(); }
  bool live() const override { return false; }
  long frame_count() const override { return static_cast<long>(replay_.size()) + limit_; }
  double fps() const override { return clip_.fps(); }
  std::vector<capture::SourceEvent> TakeEvents() override { return clip_.TakeEvents(); }
  capture::SourceStats stats() const override { return clip_.stats(); }

  std::optional<capture::FrameSet> Next(std::chrono::milliseconds timeout) override {
    std::optional<capture::FrameSet> set;
    if (!replay_.empty()) {
      set = std::move(replay_.front());
      replay_.pop_front();
    } else if (read_ < limit_) {
      set = clip_.Next(timeout);
      if (!set) return set;
      ++read_;
    } else {
      return set;
    }
    tail_.push_back(*set);
    if (tail_.size() > overlap_) tail_.pop_front();
    return set;
  }

  long read() const { return read_; }
  std::deque<capture::FrameSet> TakeTail() { return std::move(tail_); }

 private:
  capture::Source& clip_;
  std::deque<capture::FrameSet> replay_;
  long limit_ = 0;
  size_t overlap_ = 0;
  long read_ = 0;
  std::deque<capture::FrameSet> tail_;
};

struct Similarity {
  double scale = 1;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d operator*(const Eigen::Vector3d& x) const { return scale * (rotation * x) + translation; }
  Rigid3 operator*(const Rigid3& pose) const {
    Rigid3 r;
    r.rotation = rotation * pose.rotation;
    r.translation = *this * pose.translation;
    return r;
  }
};

// The similarity that carries the piece's world into the whole's, from the frames both posed:
// the rotation is the chordal mean of the frames' relative rotations (the positions of a short
// overlap lie nearly on a line, which leaves the roll about it free), the scale the ratio of the
// positions' spreads (1 when both worlds are metric: each chunk keeps its road's scale), the
// translation the one that matches the centroids. `misfit`: RMS distance left between the
// overlap's positions.
Similarity ChainSimilarity(const std::vector<std::pair<Rigid3, Rigid3>>& whole_and_piece, bool both_metric,
                           double* misfit) {
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  Eigen::Vector3d mean_w = Eigen::Vector3d::Zero(), mean_p = Eigen::Vector3d::Zero();
  for (const auto& [w, p] : whole_and_piece) {
    sum += w.rotation * p.rotation.transpose();
    mean_w += w.translation;
    mean_p += p.translation;
  }
  const double n = static_cast<double>(whole_and_piece.size());
  mean_w /= n;
  mean_p /= n;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(sum, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1 : 1;
  Similarity s;
  s.rotation = svd.matrixU() * d * svd.matrixV().transpose();
  double spread_w = 0, spread_p = 0;
  for (const auto& [w, p] : whole_and_piece) {
    spread_w += (w.translation - mean_w).norm();
    spread_p += (p.translation - mean_p).norm();
  }
  // A camera that stood still through the overlap shows no spread to take a scale from.
  if (!both_metric && spread_p > 1e-9 * n && spread_w > 1e-9 * n) s.scale = spread_w / spread_p;
  s.translation = mean_w - s.scale * (s.rotation * mean_p);
  double sq = 0;
  for (const auto& [w, p] : whole_and_piece) sq += (w.translation - s * p.translation).squaredNorm();
  *misfit = std::sqrt(sq / n);
  return s;
}

bool Metric(const Reconstruction& r) { return r.rig_height_m > 0 && r.road.found; }

// Appends `piece` to `whole`: its frames after those already there and its points, carried by
// the chaining similarity, their observations renumbered; the counts summed.
void Append(Reconstruction* whole, Reconstruction piece, long chunk_first_index, double* misfit) {
  std::map<long, int> whole_at;  // frame number -> its entry in whole
  for (int i = 0; i < static_cast<int>(whole->frames.size()); ++i)
    if (whole->frames[i].duplicate_of < 0) whole_at.emplace(whole->frames[i].index, i);
  std::vector<std::pair<Rigid3, Rigid3>> shared;
  for (const auto& f : piece.frames) {
    auto it = whole_at.find(f.index);
    if (it == whole_at.end() || f.duplicate_of >= 0 || f.interpolated || whole->frames[it->second].interpolated)
      continue;
    shared.emplace_back(whole->frames[it->second].world_from_rig, f.world_from_rig);
  }
  if (shared.size() < 2)
    throw Error("reconstruct", "the chunk from frame " + std::to_string(chunk_first_index) + " shares " +
                                   std::to_string(shared.size()) +
                                   " posed frame(s) with the one before (need 2): it cannot be chained");
  const Similarity s = ChainSimilarity(shared, Metric(*whole) && Metric(piece), misfit);

  std::vector<int> renumber(piece.frames.size(), -1);
  for (int i = 0; i < static_cast<int>(piece.frames.size()); ++i) {
    ReconstructedFrame f = piece.frames[i];
    auto it = whole_at.find(f.index);
    if (it != whole_at.end() && f.duplicate_of < 0) {
      renumber[i] = it->second;
      continue;
    }
    if (f.index <= whole->frames.back().index) continue;  // a repeat of a frame kept before
    f.world_from_rig = s * f.world_from_rig;
    if (f.duplicate_of >= 0) f.duplicate_of = renumber[f.duplicate_of];
    renumber[i] = static_cast<int>(whole->frames.size());
    whole->frames.push_back(f);
  }
  for (auto& p : piece.points) {
    p.position = s * p.position;
    std::vector<PointObservation> kept;
    for (auto o : p.observations)
      if (renumber[o.frame] >= 0) {
        o.frame = renumber[o.frame];
        kept.push_back(o);
      }
    if (kept.size() < 2) continue;
    p.observations = std::move(kept);
    whole->points.push_back(std::move(p));
  }

  const double n_whole = whole->observations, n_piece = piece.observations;
  if (n_whole + n_piece > 0)
    whole->rmse_px = std::sqrt((n_whole * whole->rmse_px * whole->rmse_px + n_piece * piece.rmse_px * piece.rmse_px) /
                               (n_whole + n_piece));
  whole->observations += piece.observations;
  whole->cross_camera_links += piece.cross_camera_links;
  for (size_t c = 0; c < whole->tracks_per_camera.size() && c < piece.tracks_per_camera.size(); ++c)
    whole->tracks_per_camera[c] += piece.tracks_per_camera[c];
  for (size_t c = 0; c < whole->camera_contributions.size() && c < piece.camera_contributions.size(); ++c) {
    whole->camera_contributions[c].observations += piece.camera_contributions[c].observations;
    whole->camera_contributions[c].inliers += piece.camera_contributions[c].inliers;
    whole->camera_contributions[c].rejected += piece.camera_contributions[c].rejected;
  }
  TrifocalCheckSummary& t = whole->trifocal;
  const TrifocalCheckSummary& u = piece.trifocal;
  t.tracks_before += u.tracks_before, t.tracks_after += u.tracks_after;
  t.observations_before += u.observations_before, t.observations_after += u.observations_after;
  t.triples_checked += u.triples_checked, t.triples_unchecked += u.triples_unchecked;
  t.triples_tested += u.triples_tested, t.triples_rejected += u.triples_rejected;
  t.tracks_split += u.tracks_split, t.untested_observations += u.untested_observations;
  t.seconds += u.seconds;
  for (const auto& stage : piece.stages) {
    auto it = std::find_if(whole->stages.begin(), whole->stages.end(),
                           [&](const ReconstructionStage& w) { return w.name == stage.name; });
    if (it == whole->stages.end()) {
      whole->stages.push_back(stage);
    } else {
      it->seconds += stage.seconds;
      it->inliers += stage.inliers;
    }
  }
  whole->dropped_frames.insert(whole->dropped_frames.end(), piece.dropped_frames.begin(), piece.dropped_frames.end());
  for (const auto& w : piece.warnings)
    if (std::find(whole->warnings.begin(), whole->warnings.end(), w) == whole->warnings.end())
      whole->warnings.push_back(w);
}

}  // namespace

Reconstruction ReconstructInChunks(capture::Source& source, const ReconstructionOptions& options,
                                   const ReconstructionCallbacks& callbacks, const ReconstructPiece& piece) {
  const size_t overlap = static_cast<size_t>(options.chunk_overlap);
  const long clip_frames = options.max_frames > 0 ? options.max_frames : source.frame_count();
  Reconstruction whole;
  std::deque<capture::FrameSet> carried;
  long read = 0;  // frame sets read from the clip
  int chunks = 0;
  double worst_misfit = 0, chain_seconds = 0;
  while (options.max_frames == 0 || read < options.max_frames) {
    auto ahead = source.Next();  // a chunk starts only where the clip goes on
    if (!ahead) break;
    ++read;
    const long first_index = ahead->frames.empty() ? ahead->index : ahead->frames.front().index;
    carried.push_back(std::move(*ahead));
    long limit = options.chunk_frames - static_cast<long>(carried.size());
    if (options.max_frames > 0) limit = std::min(limit, options.max_frames - read);
    ChunkSource chunk(source, std::move(carried), limit, overlap);
    const long offset = read - 1 - static_cast<long>(chunks > 0 ? overlap : 0);
    ReconstructionCallbacks inner = callbacks;
    if (callbacks.progress)
      inner.progress = [&, offset](const std::string& stage, int done, int total) {
        if (stage == "tracking" && clip_frames > 0)
          callbacks.progress(stage, static_cast<int>(std::min(clip_frames, offset + done)),
                             static_cast<int>(clip_frames));
        else
          callbacks.progress("chunk " + std::to_string(chunks + 1) + " " + stage, done, total);
      };
    Reconstruction part = piece(chunk, inner);
    read += chunk.read();
    carried = chunk.TakeTail();
    if (chunks++ == 0) {
      whole = std::move(part);
    } else {
      const auto t0 = SteadyClock::now();
      double misfit = 0;
      Append(&whole, std::move(part), first_index, &misfit);
      chain_seconds += SecondsSince(t0);
      worst_misfit = std::max(worst_misfit, misfit);
    }
    if (chunk.read() < limit) break;  // the clip ended inside this chunk
  }
  if (chunks > 1) {
    // Seconds and counts are summed over the chunks; the words describe the first.
    for (auto& stage : whole.stages)
      stage.what = "(summed over " + std::to_string(chunks) + " chunks; the first:) " + stage.what;
    whole.stages.push_back({"chunks", chain_seconds, chunks,
                            "chunks of at most " + std::to_string(options.chunk_frames) + " frames overlapping by " +
                                std::to_string(overlap) + ", chained by their shared frames (worst misfit " +
                                std::to_string(worst_misfit) + " units)"});
  }
  return whole;
}

}  // namespace odvr::tracking
