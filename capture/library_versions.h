#pragma once
#include "engine/library_versions.h"

namespace odvr {
// libcamera, libv4l2 and libav (video files), which only capture links.
LibraryVersions CaptureLibraryVersions();
}  // namespace odvr
