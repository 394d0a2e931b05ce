#pragma once
// What every fuzz target shares. odvr's loaders read files, so each input is written to a file of
// this process (named by the kind of data its first bytes announce, since some readers choose by
// extension), and the loader reads it as it reads a user's file.
//
// The contract a target checks is the loaders' own: malformed input ends in odvr::Error (a one-line
// message naming the file), never in a crash, a sanitizer report, a hang, or another exception.
// odvr::Error is caught; anything else escapes to libFuzzer, which reports it as a crash.
// fuzz_input.cpp's LLVMFuzzerInitialize, linked into every target, quiets odvr's own log.
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace odvr::fuzz {

inline bool StartsWith(const std::uint8_t* data, std::size_t size, const std::string& prefix, std::size_t at = 0) {
  return size >= at + prefix.size() && std::equal(prefix.begin(), prefix.end(), data + at);
}

// Writes the input to /tmp/odvr_fuzz_<pid><extension> and returns that path.
inline std::filesystem::path WriteInput(const std::uint8_t* data, std::size_t size, const std::string& extension) {
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("odvr_fuzz_" + std::to_string(::getpid()) + extension);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

}  // namespace odvr::fuzz
