#pragma once
// One equirectangular camera's frames as structure from motion wants them: one eye of a stereo
// video, every step-th frame, scaled down to a tracking width. Consumer 360° cameras record mono
// equirect (2:1), or stereo as two 2:1 eyes stacked top-bottom (1:1) or side by side (4:1).
#include <memory>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/rig.h"
#include "capture/source.h"

namespace odvr::capture {

enum class StereoLayout { kMono, kTopBottom, kSideBySide };

// "mono", "top-bottom", "side-by-side" (also "tb", "sbs").
StereoLayout ParseStereoLayout(const std::string& name);
std::string ToString(StereoLayout layout);
// The layout a frame's shape implies: 1:1 top-bottom, 4:1 side by side, otherwise mono.
StereoLayout GuessStereoLayout(int width, int height);

struct EquirectViewOptions {
  StereoLayout layout = StereoLayout::kMono;
  int eye = 0;         // 0: the top or left eye, 1: the other
  int width = 0;       // scale the eye to width x width/2 (INTER_AREA); 0 keeps its size
  long step = 1;       // deliver every step-th frame of the source
  void Check() const;  // throws odvr::Error naming the bad field
};

// Wraps a one-camera source. Frame indices and timestamps stay the source's, so a trajectory made
// from the view names the video's own frames. Throws odvr::Error when `source` has more than one
// camera.
std::unique_ptr<Source> OpenEquirectView(std::unique_ptr<Source> source, const EquirectViewOptions& options);

// A one-camera clip opened as structure from motion reads it.
struct EquirectClip {
  std::unique_ptr<Source> source;  // the eye, scaled, stepped, from the first frame asked for
  StereoLayout layout = StereoLayout::kMono;
  std::string layout_from;     // "its metadata", "the caller" or "the frame's shape"
  bool eye_resampled = false;  // the eye was not 2:1 (its metadata says equirect): rows resampled
  int width = 0;               // of the frames delivered (height width / 2)
};
// `raw` (one camera) from frame `first`: the layout `stereo` names, else the one the video file
// `name` declares in its metadata, else the one the first frame's shape implies; the eye checked
// to be a 2:1 image, or one the file's metadata declares equirectangular (resampled to 2:1; a
// file whose metadata names another projection is refused); scaled to at most `max_width`.
// Throws odvr::Error naming `name` for a clip with no decodable frame or an eye not 2:1.
EquirectClip OpenEquirectClip(std::unique_ptr<Source> raw, const std::string& name, std::optional<StereoLayout> stereo,
                              int eye, int max_width, long step, long first);

// The eye's size once cropped from a width x height frame (before any scaling).
void EyeSize(StereoLayout layout, int width, int height, int* eye_width, int* eye_height);

// Rows within `cap_deg` of straight down of a width x height equirect image, as an 8-bit mask
// (255 there): where a handheld camera sees its operator and a mounted one its mount.
cv::Mat NadirCapMask(int width, int height, double cap_deg);

// The six 90° cube faces of an equirect camera, as COLMAP users split 360° frames: pinhole
// cameras of `size` x `size` at its centre (front, right, back, left, up, down), named
// <camera>_<face>, their rig_from_cam the equirect camera's turned to each face.
std::vector<RigCamera> CubeFaceCameras(const RigCamera& equirect, int size);
// A face's image sampled from the equirect camera's (bilinear, the seam wrapped).
cv::Mat CubeFaceImage(const cv::Mat& equirect_image, const RigCamera& equirect, const RigCamera& face);

// A one-camera rig: an upright equirectangular camera at the rig centre (its image's centre
// column looks along the rig's x, forward; row 0 is the zenith), `height_m` above the road
// (0: unknown).
Rig EquirectCameraRig(int width, int height, double height_m);

}  // namespace odvr::capture
