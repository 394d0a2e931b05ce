#include <iostream>
#include <nlohmann/json.hpp>

#include "app/cli/commands.h"
#include "capture/library_versions.h"
#include "core/error.h"
#include "engine/gl/context.h"
#include "tracking/library_versions.h"

namespace odvr::app {
namespace {

struct InfoOptions {
  bool json = false;
};

nlohmann::json ToJson(const gl::ContextInfo& i) {
  return {{"platform", i.platform},
          {"vendor", i.vendor},
          {"renderer", i.renderer},
          {"version", i.version},
          {"glsl_version", i.glsl_version},
          {"major", i.major},
          {"minor", i.minor},
          {"core_profile", i.core_profile},
          {"compute",
           {{"max_invocations", i.max_compute_invocations},
            {"max_group_count", i.max_compute_group_count},
            {"max_group_size", i.max_compute_group_size},
            {"max_shared_bytes", i.max_compute_shared_bytes}}},
          {"max_ssbo_bytes", i.max_ssbo_bytes},
          {"max_texture_size", i.max_texture_size},
          {"max_3d_texture_size", i.max_3d_texture_size}};
}

int RunInfo(const InfoOptions& options) {
  LibraryVersions libs = EngineLibraryVersions();
  for (auto& l : CaptureLibraryVersions()) libs.push_back(l);
  for (auto& l : TrackingLibraryVersions()) libs.push_back(l);

  std::string gl_error;
  gl::ContextInfo info;
  try {
    gl::HeadlessContext context;
    info = context.Info();
  } catch (const Error& e) {
    gl_error = e.what();
  }

  if (options.json) {
    nlohmann::json out;
    out["odvr"] = ODVR_VERSION;
    out["gl"] = gl_error.empty() ? ToJson(info) : nlohmann::json{{"error", gl_error}};
    for (const auto& [name, version] : libs) out["libraries"][name] = version;
    std::cout << out.dump(2) << "\n";
  } else {
    std::cout << "odvr " << ODVR_VERSION << "\n";
    if (gl_error.empty()) {
      std::cout << "OpenGL   " << info.version << (info.core_profile ? " (core)" : "") << " via " << info.platform
                << "\n         " << info.vendor << " / " << info.renderer << "\nGLSL     " << info.glsl_version
                << "\ncompute  " << info.max_compute_invocations << " invocations per group, group size ≤ "
                << info.max_compute_group_size[0] << "×" << info.max_compute_group_size[1] << "×"
                << info.max_compute_group_size[2] << ", groups ≤ " << info.max_compute_group_count[0] << "×"
                << info.max_compute_group_count[1] << "×" << info.max_compute_group_count[2] << ", "
                << info.max_compute_shared_bytes << " B shared, SSBO ≤ " << (info.max_ssbo_bytes >> 20) << " MiB\n";
    } else {
      std::cout << "OpenGL   unavailable: " << gl_error << "\n";
    }
    std::cout << "libraries";
    for (const auto& [name, version] : libs) std::cout << " " << name << " " << version << ";";
    std::cout << "\n";
  }
  if (!gl_error.empty()) throw Error("OpenGL", gl_error);
  return 0;
}

}  // namespace

CommandFn AddInfo(CLI::App* sub) {
  auto options = std::make_shared<InfoOptions>();
  sub->add_flag("--json", options->json, "Print one JSON object");
  return [options] { return RunInfo(*options); };
}

}  // namespace odvr::app
