#include "core/atomic_file.h"

#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cstring>
#include <fstream>
#include <system_error>

#include "core/error.h"

namespace odvr {
namespace {

namespace fs = std::filesystem;

// Registered temporaries: fixed storage, so a signal handler reads them without allocating. A
// slot is claimed by compare-and-swap from 0 to 1 (writing), published as 2 once its path is in.
constexpr std::size_t kSlots = 32, kPathBytes = 1024;
struct Slot {
  std::atomic<int> state{0};
  char path[kPathBytes] = {};
};
std::array<Slot, kSlots> g_slots;

}  // namespace

void RegisterTemporaryFile(const fs::path& path) {
  const std::string s = path.string();
  if (s.size() + 1 > kPathBytes) return;
  for (Slot& slot : g_slots) {
    int expected = 0;
    if (!slot.state.compare_exchange_strong(expected, 1)) continue;
    std::memcpy(slot.path, s.c_str(), s.size() + 1);
    slot.state.store(2);
    return;
  }
}

void ReleaseTemporaryFile(const fs::path& path) {
  const std::string s = path.string();
  for (Slot& slot : g_slots)
    if (slot.state.load() == 2 && s == slot.path) {
      slot.path[0] = '\0';
      slot.state.store(0);
      return;
    }
}

void RemoveTemporaryFiles() {
  // Files first, then the folders they were in (rmdir removes only an empty one).
  for (Slot& slot : g_slots)
    if (slot.state.load() == 2 && slot.path[0] != '\0') ::unlink(slot.path);
  for (Slot& slot : g_slots)
    if (slot.state.load() == 2 && slot.path[0] != '\0') ::rmdir(slot.path);
}

void CheckReplaceableOutput(const fs::path& path) {
  std::error_code ec;
  const fs::file_status s = fs::symlink_status(path, ec);
  if (ec || !fs::exists(s)) return;
  const char* what = fs::is_symlink(s)                                  ? "a symbolic link"
                     : fs::is_directory(s)                              ? "a directory"
                     : fs::is_fifo(s)                                   ? "a FIFO"
                     : fs::is_block_file(s) || fs::is_character_file(s) ? "a device"
                     : fs::is_socket(s)                                 ? "a socket"
                                                                        : nullptr;
  if (what) throw Error(path.string(), std::string("is ") + what + ", not a regular file: refusing to replace it");
}

void WriteFileAtomically(const fs::path& path, const std::function<void(const fs::path&)>& write) {
  CheckReplaceableOutput(path);
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
  RegisterTemporaryFile(tmp);
  const auto discard = [&] {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    ReleaseTemporaryFile(tmp);
  };
  try {
    write(tmp);
  } catch (...) {
    discard();
    throw;
  }
  if (!fs::is_regular_file(tmp, ec)) {
    discard();
    throw Error(path.string(), "cannot write: the writer produced no file");
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    const std::string why = ec.message();  // before the clean-up overwrites it
    discard();
    throw Error(path.string(), "cannot write (rename failed): " + why);
  }
  ReleaseTemporaryFile(tmp);
}

void WriteTextFilesAtomically(const fs::path& dir, const std::vector<std::pair<std::string, std::string>>& files) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw Error(dir.string(), "cannot create directory: " + ec.message());
  std::vector<fs::path> tmps;
  const auto discard = [&] {
    std::error_code ignored;
    for (const auto& t : tmps) {
      fs::remove(t, ignored);
      ReleaseTemporaryFile(t);
    }
  };
  try {
    for (const auto& [name, text] : files) {
      const fs::path target = dir / name;
      CheckReplaceableOutput(target);
      tmps.push_back(dir / ("." + name + ".tmp" + std::to_string(::getpid())));
      RegisterTemporaryFile(tmps.back());
      std::ofstream out(tmps.back(), std::ios::binary);
      out << text;
      out.close();
      if (!out) throw Error(target.string(), "cannot write (disk full, or no permission?)");
    }
  } catch (...) {
    discard();
    throw;
  }
  sigset_t interrupts, previous;
  sigemptyset(&interrupts);
  sigaddset(&interrupts, SIGINT);
  sigaddset(&interrupts, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &interrupts, &previous);
  std::string failed;
  for (std::size_t i = 0; i < files.size() && failed.empty(); ++i) {
    fs::rename(tmps[i], dir / files[i].first, ec);
    if (ec) failed = (dir / files[i].first).string() + ": cannot write (rename failed): " + ec.message();
  }
  for (const auto& t : tmps) ReleaseTemporaryFile(t);
  pthread_sigmask(SIG_SETMASK, &previous, nullptr);
  if (!failed.empty()) {
    discard();
    throw Error("output set", failed);
  }
}

void WriteTextAtomically(const fs::path& path, const std::string& text) {
  WriteFileAtomically(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out << text;
    out.close();
    if (!out) throw Error(path.string(), "cannot write (disk full, or no permission?)");
  });
}

}  // namespace odvr
