#include "capture/library_versions.h"

#include <libcamera/camera_manager.h>

#include <string>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libswscale/swscale.h>
}

namespace odvr {
namespace {

// libav packs its runtime version as major << 16 | minor << 8 | micro.
std::string LibavVersion(unsigned v) {
  return std::to_string(v >> 16) + "." + std::to_string((v >> 8) & 0xff) + "." + std::to_string(v & 0xff);
}

}  // namespace

LibraryVersions CaptureLibraryVersions() {
  // libv4l2 has no version query; the build's pkg-config version is what was linked.
  return {{"libcamera", libcamera::CameraManager::version()},
          {"libv4l2", ODVR_LIBV4L2_VERSION},
          {"libavformat", LibavVersion(avformat_version())},
          {"libavcodec", LibavVersion(avcodec_version())},
          {"libswscale", LibavVersion(swscale_version())}};
}

}  // namespace odvr
