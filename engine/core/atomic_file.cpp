#include "engine/core/atomic_file.h"

#include <unistd.h>

#include <fstream>
#include <system_error>

#include "engine/core/error.h"

namespace odvr {

void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(const std::filesystem::path&)>& write) {
  namespace fs = std::filesystem;
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw Error(dir.string(), "cannot create directory: " + ec.message());
  // Built by appending: GCC 12 at -O3 takes `"." + std::string` for an overlapping memcpy
  // (-Wrestrict, a false positive) and a Release build with ODVR_WERROR fails.
  std::string name = ".";
  name += path.stem().string();
  name += ".tmp" + std::to_string(::getpid());
  name += path.extension().string();
  const fs::path tmp = dir / name;
  try {
    write(tmp);
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw Error(path.string(), "cannot write (rename failed): " + ec.message());
  }
}

void WriteTextAtomically(const std::filesystem::path& path, const std::string& text) {
  WriteFileAtomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out << text;
    out.flush();
    if (!out) throw Error(path.string(), "cannot write");
  });
}

}  // namespace odvr
