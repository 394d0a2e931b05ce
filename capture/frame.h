#pragma once
// What capture hands to the rest of odvr: timestamped frames from N cameras, grouped into frame
// sets that belong to one instant. Images stay as decoded (8-bit BGR, OpenCV's order); the
// stitcher linearizes them.
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

namespace odvr::capture {

struct Frame {
  int camera = 0;
  double timestamp_s = 0;
  long index = 0;  // position in the camera's own stream
  cv::Mat image;   // empty when the camera delivered nothing for this set
};

struct FrameSet {
  long index = 0;  // running count of sets delivered by the source
  double timestamp_s = 0;
  std::vector<Frame> frames;  // one per camera, in camera order; frames[c].image.empty() = missing

  int missing_count() const {
    int n = 0;
    for (const auto& f : frames) n += f.image.empty();
    return n;
  }
};

// Something a caller can survive: a camera lost, a corrupt frame skipped, frames dropped.
struct SourceEvent {
  enum class Kind { kCameraLost, kCorruptFrame, kDroppedFrames, kOutOfSync };
  Kind kind;
  int camera = -1;
  long frame_index = -1;
  std::string message;
};

struct SourceStats {
  long sets_delivered = 0;
  long frames_dropped = 0;      // queue overflow (drop oldest)
  long frames_out_of_sync = 0;  // no partner within the sync tolerance
  long corrupt_frames = 0;
  long missing_frames = 0;  // camera slots left empty in delivered sets
};

}  // namespace odvr::capture
