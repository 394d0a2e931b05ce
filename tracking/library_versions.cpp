#include "tracking/library_versions.h"

#include <ceres/version.h>

#include <Eigen/Core>
#include <string>

namespace odvr {

LibraryVersions TrackingLibraryVersions() {
  return {{"ceres", CERES_VERSION_STRING},
          {"eigen", std::to_string(EIGEN_WORLD_VERSION) + "." + std::to_string(EIGEN_MAJOR_VERSION) + "." +
                        std::to_string(EIGEN_MINOR_VERSION)},
          // OpenGV ships no version macro; Debian 12 packages 1.0.
          {"opengv", "1.0"}};
}

}  // namespace odvr
