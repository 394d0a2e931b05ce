#include "capture/library_versions.h"

#include <libcamera/camera_manager.h>

namespace odvr {

LibraryVersions CaptureLibraryVersions() {
  // libv4l2 has no version query; the build's pkg-config version is what was linked.
  return {{"libcamera", libcamera::CameraManager::version()}, {"libv4l2", ODVR_LIBV4L2_VERSION}};
}

}  // namespace odvr
