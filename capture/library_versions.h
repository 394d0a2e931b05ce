#pragma once
#include "engine/core/library_versions.h"

namespace odvr {
// libcamera and libv4l2, which only capture links.
LibraryVersions CaptureLibraryVersions();
}  // namespace odvr
