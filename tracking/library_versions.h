#pragma once
#include "engine/library_versions.h"

namespace odvr {
// Ceres, Eigen and OpenGV, which only tracking links.
LibraryVersions TrackingLibraryVersions();
}  // namespace odvr
