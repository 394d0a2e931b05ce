#pragma once
// GLSL sources from shaders/, embedded into the binary at build time. An override directory
// (SetOverrideDirectory, or the ODVR_SHADER_DIR environment variable) is searched first, so a
// shader can be edited live without rebuilding. `#include "x.glsl"` is resolved here, with
// #line directives so that compile errors name the right file and line.
#include <filesystem>
#include <string>
#include <vector>

#include "engine/gl/objects.h"

namespace odvr::gl {

class ShaderLibrary {
 public:
  static void SetOverrideDirectory(const std::filesystem::path& dir);
  static std::filesystem::path OverrideDirectory();

  // Names of the embedded shaders ("lighting_project.comp", ...).
  static std::vector<std::string> Names();

  // Raw text of one shader, from the override directory if present there, else embedded.
  // Throws odvr::Error naming the shader when it exists in neither.
  static std::string Source(const std::string& name);

  // `defines` are inserted after the #version line ("#define X 1\n...").
  // Compile and link errors throw odvr::Error whose message starts "name:line: ".
  static Program Compute(const std::string& name, const std::string& defines = "");
  static Program Graphics(const std::string& vertex_name, const std::string& fragment_name,
                          const std::string& defines = "");
};

}  // namespace odvr::gl
