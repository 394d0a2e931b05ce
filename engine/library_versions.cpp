#include "engine/library_versions.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <OpenImageIO/oiioversion.h>
#include <spdlog/version.h>

#include <glm/detail/setup.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core/version.hpp>
#include <string>

namespace odvr {

LibraryVersions EngineLibraryVersions() {
  auto v3 = [](int a, int b, int c) { return std::to_string(a) + "." + std::to_string(b) + "." + std::to_string(c); };
  return {
      {"glfw", glfwGetVersionString()},
      {"glm", v3(GLM_VERSION_MAJOR, GLM_VERSION_MINOR, GLM_VERSION_PATCH)},
      {"openimageio", OIIO_VERSION_STRING},
      {"opencv", CV_VERSION},
      {"spdlog", v3(SPDLOG_VER_MAJOR, SPDLOG_VER_MINOR, SPDLOG_VER_PATCH)},
      {"nlohmann_json", v3(NLOHMANN_JSON_VERSION_MAJOR, NLOHMANN_JSON_VERSION_MINOR, NLOHMANN_JSON_VERSION_PATCH)},
  };
}

}  // namespace odvr
