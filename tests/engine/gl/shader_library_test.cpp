#include "engine/gl/shader_library.h"

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "tests/engine/gl/gl_test_context.h"

namespace odvr::gl {
namespace {

namespace fs = std::filesystem;

class ShaderLibraryGL : public odvr::testing::GlTest {
 protected:
  void SetUp() override {
    GlTest::SetUp();
    dir_ = fs::temp_directory_path() / ("odvr_shader_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    ShaderLibrary::SetOverrideDirectory(dir_);
  }
  void TearDown() override {
    ShaderLibrary::SetOverrideDirectory({});
    fs::remove_all(dir_);
  }
  void Write(const std::string& name, const std::string& text) { std::ofstream(dir_ / name) << text; }
  std::string CompileError(const std::string& name) {
    try {
      ShaderLibrary::Compute(name);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

TEST_F(ShaderLibraryGL, EmbedsShadersFromTheSourceTree) {
  const auto names = ShaderLibrary::Names();
  EXPECT_NE(std::find(names.begin(), names.end(), "equirect_directions.comp"), names.end());
  EXPECT_NE(ShaderLibrary::Source("equirect.glsl").find("equirectDirection"), std::string::npos);
}

TEST_F(ShaderLibraryGL, SyntaxErrorNamesFileAndLine) {
  Write("broken.comp",
        "#version 450\n"
        "layout(local_size_x = 1) in;\n"
        "void main() {\n"
        "  float x = 1.0\n"  // line 4: missing semicolon, reported on line 4 or 5
        "  x += 1.0;\n"
        "}\n");
  const std::string message = CompileError("broken.comp");
  EXPECT_NE(message.find("shaders/broken.comp:"), std::string::npos) << message;
  EXPECT_TRUE(message.find("broken.comp:4") != std::string::npos || message.find("broken.comp:5") != std::string::npos)
      << message;
}

TEST_F(ShaderLibraryGL, ErrorInAnIncludedFileNamesThatFile) {
  Write("helper.glsl", "float helper() {\n  return undefined_name;\n}\n");
  Write("user.comp",
        "#version 450\n"
        "#include \"helper.glsl\"\n"
        "layout(local_size_x = 1) in;\n"
        "void main() { helper(); }\n");
  const std::string message = CompileError("user.comp");
  EXPECT_NE(message.find("shaders/helper.glsl:2"), std::string::npos) << message;
}

TEST_F(ShaderLibraryGL, OverrideDirectoryWinsOverEmbedded) {
  Write("equirect.glsl", "// overridden\n");
  EXPECT_EQ(ShaderLibrary::Source("equirect.glsl"), "// overridden\n");
}

TEST_F(ShaderLibraryGL, MissingShaderIsAClearError) {
  EXPECT_NE(CompileError("no_such_shader.comp").find("no_such_shader.comp"), std::string::npos);
}

}  // namespace
}  // namespace odvr::gl
