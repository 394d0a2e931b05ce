#include "app/bench/bench_common.h"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <thread>

#include "core/atomic_file.h"

namespace odvr::app {

void WritePlot(const std::filesystem::path& dir, const std::string& stem, int width, int height,
               const std::string& body, const std::string& bench) {
  const std::string script = stem + ".gnuplot";
  WriteTextAtomically(dir / script, fmt::format("set terminal pngcairo size {},{} noenhanced\nset output '{}.png'\n{}",
                                                width, height, stem, body));
  const std::string command = "cd " + ShellQuote(dir.string()) + " && gnuplot " + ShellQuote(script) + " 2>/dev/null";
  if (std::system(command.c_str()) != 0)
    spdlog::warn("{}: gnuplot failed; the table and its data are written, the plot is not", bench);
}

std::string ShellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string BenchMachineDescription() {
  std::string model = "unknown CPU";
  std::ifstream cpuinfo("/proc/cpuinfo");
  for (std::string line; std::getline(cpuinfo, line);)
    if (line.rfind("model name", 0) == 0) {
      model = line.substr(line.find(':') + 2);
      break;
    }
  return model + ", " + std::to_string(std::thread::hardware_concurrency()) + " cores";
}

BenchProgress::BenchProgress(std::string what, long total) : what_(std::move(what)), total_(total) {}

void BenchProgress::Step(const std::string& done) {
  ++done_;
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double eta = done_ > 0 ? elapsed / done_ * (total_ - done_) : 0;
  const std::string line =
      fmt::format("{}: {}/{} ({}) {:.0f} s elapsed, ETA {:.0f} s", what_, done_, total_, done, elapsed, eta);
  // On a terminal the line rewrites itself; in a log each step is its own line.
  if (isatty(STDERR_FILENO))
    std::cerr << "\r\033[K" << line << (done_ == total_ ? "\n" : "") << std::flush;
  else
    std::cerr << line << "\n";
}

}  // namespace odvr::app
