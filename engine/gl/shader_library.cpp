#include "engine/gl/shader_library.h"

#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <sstream>

#include "core/error.h"

namespace odvr::gl {

const std::map<std::string, std::string>& EmbeddedShaders();  // generated at build time

namespace {

std::mutex g_mutex;
std::filesystem::path g_override_dir;

bool ReadOverride(const std::string& name, std::string* text) {
  std::filesystem::path dir;
  {
    std::lock_guard lock(g_mutex);
    dir = g_override_dir;
  }
  if (dir.empty()) {
    if (const char* env = std::getenv("ODVR_SHADER_DIR")) dir = env;
  }
  if (dir.empty()) return false;
  std::ifstream in(dir / name, std::ios::binary);
  if (!in) return false;
  std::stringstream ss;
  ss << in.rdbuf();
  *text = ss.str();
  return true;
}

// Expands #include lines. Each file gets a GLSL source-string number (its index in `files`);
// #line N ID keeps compiler line numbers pointing into the original files.
std::string Preprocess(const std::string& name, const std::string& defines, std::vector<std::string>* files,
                       int depth = 0) {
  if (depth > 8) throw Error("shaders/" + name, "#include nested too deeply (a cycle?)");
  const int id = static_cast<int>(files->size());
  files->push_back(name);
  std::istringstream in(ShaderLibrary::Source(name));
  std::ostringstream out;
  static const std::regex include_re(R"(^\s*#\s*include\s+"([^"]+)\"\s*$)");
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    std::smatch m;
    if (line.find("GL_GOOGLE_include_directive") != std::string::npos) {
      // Only there for glslangValidator's build-time check; drivers resolve nothing themselves.
      out << "\n";
    } else if (std::regex_match(line, m, include_re)) {
      out << "#line 1 " << files->size() << "\n";
      out << Preprocess(m[1].str(), "", files, depth + 1);
      out << "#line " << line_no + 1 << " " << id << "\n";
    } else {
      out << line << "\n";
      if (depth == 0 && line.rfind("#version", 0) == 0) {
        out << defines;
        out << "#line " << line_no + 1 << " " << id << "\n";
      }
    }
  }
  return out.str();
}

// Rewrites driver messages such as Mesa's "1:12(5): error: ..." or NVIDIA's "1(12) : error ..."
// into "shaders/name.glsl:12: error: ...".
std::string MapLog(const std::string& log, const std::vector<std::string>& files, std::string* first_where) {
  static const std::regex loc_re(R"(^(\d+)(?::(\d+)\(\d+\)|\((\d+)\))\s*:?\s*(.*)$)");
  std::istringstream in(log);
  std::ostringstream out;
  std::string line;
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_match(line, m, loc_re)) {
      const std::size_t id = std::stoul(m[1].str());
      const std::string ln = m[2].matched ? m[2].str() : m[3].str();
      const std::string file = id < files.size() ? files[id] : "?";
      const std::string where = "shaders/" + file + ":" + ln;
      if (first_where->empty()) *first_where = where;
      out << where << ": " << m[4].str() << "\n";
    } else if (!line.empty()) {
      out << line << "\n";
    }
  }
  std::string s = out.str();
  while (!s.empty() && s.back() == '\n') s.pop_back();
  return s;
}

GLuint CompileStage(GLenum stage, const std::string& name, const std::string& defines) {
  std::vector<std::string> files;
  const std::string source = Preprocess(name, defines, &files);
  GLuint shader = glCreateShader(stage);
  const char* src = source.c_str();
  glShaderSource(shader, 1, &src, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    GLint len = 0;
    glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &len);
    std::string log(static_cast<std::size_t>(std::max(len, 1)), '\0');
    glGetShaderInfoLog(shader, len, nullptr, log.data());
    glDeleteShader(shader);
    std::string where;
    const std::string mapped = MapLog(log.c_str(), files, &where);
    // One line for the user: the first located message, the rest goes with it.
    throw Error(where.empty() ? "shaders/" + name : where, "GLSL compile error: " + mapped);
  }
  return shader;
}

Program Link(const std::vector<GLuint>& shaders, const std::string& label) {
  GLuint program = glCreateProgram();
  for (GLuint s : shaders) glAttachShader(program, s);
  glLinkProgram(program);
  for (GLuint s : shaders) {
    glDetachShader(program, s);
    glDeleteShader(s);
  }
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    GLint len = 0;
    glGetProgramiv(program, GL_INFO_LOG_LENGTH, &len);
    std::string log(static_cast<std::size_t>(std::max(len, 1)), '\0');
    glGetProgramInfoLog(program, len, nullptr, log.data());
    glDeleteProgram(program);
    throw Error("shaders/" + label, "GLSL link error: " + std::string(log.c_str()));
  }
  return Program::wrap(program);
}

}  // namespace

void ShaderLibrary::SetOverrideDirectory(const std::filesystem::path& dir) {
  std::lock_guard lock(g_mutex);
  g_override_dir = dir;
}

std::filesystem::path ShaderLibrary::OverrideDirectory() {
  std::lock_guard lock(g_mutex);
  return g_override_dir;
}

std::vector<std::string> ShaderLibrary::Names() {
  std::vector<std::string> names;
  for (const auto& [name, text] : EmbeddedShaders()) names.push_back(name);
  return names;
}

std::string ShaderLibrary::Source(const std::string& name) {
  std::string text;
  if (ReadOverride(name, &text)) return text;
  const auto& embedded = EmbeddedShaders();
  auto it = embedded.find(name);
  if (it == embedded.end()) throw Error("shaders/" + name, "no such shader (embedded or in the override directory)");
  return it->second;
}

Program ShaderLibrary::Compute(const std::string& name, const std::string& defines) {
  return Link({CompileStage(GL_COMPUTE_SHADER, name, defines)}, name);
}

Program ShaderLibrary::Graphics(const std::string& vertex_name, const std::string& fragment_name,
                                const std::string& defines) {
  GLuint vs = CompileStage(GL_VERTEX_SHADER, vertex_name, defines);
  GLuint fs = 0;
  try {
    fs = CompileStage(GL_FRAGMENT_SHADER, fragment_name, defines);
  } catch (...) {
    glDeleteShader(vs);
    throw;
  }
  return Link({vs, fs}, vertex_name + "+" + fragment_name);
}

}  // namespace odvr::gl
