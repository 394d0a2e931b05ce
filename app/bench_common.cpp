#include "app/bench_common.h"

#include <spdlog/fmt/fmt.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <iostream>
#include <thread>

namespace odvr::app {

double Median(std::vector<double> values) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
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
