#pragma once
// What every `odvr bench …` shares: medians, the machine a figure was measured on, and progress
// with an ETA on a terminal (benchmarks run for minutes).
#include <chrono>
#include <string>
#include <vector>

namespace odvr::app {

double Median(std::vector<double> values);

// CPU model and core count, for the header of a benchmark table.
std::string BenchMachineDescription();

class BenchProgress {
 public:
  BenchProgress(std::string what, long total);
  void Step(const std::string& done);  // one unit done: prints progress and ETA on stderr

 private:
  std::string what_;
  long total_ = 0, done_ = 0;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

}  // namespace odvr::app
