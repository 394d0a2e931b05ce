#pragma once
// What every `odvr bench …` shares: medians, the machine a figure was measured on, and progress
// with an ETA on a terminal (benchmarks run for minutes).
#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include "core/statistics.h"

namespace odvr::app {

// Where a bench writes its table, TSV and plot unless --out says: a folder in the working
// directory. The committed pages are regenerated only by naming them (--out docs/benchmarks), so
// a run on a busy laptop never replaces them by accident.
inline constexpr const char* kBenchOutDir = "odvr-bench";

// CPU model and core count, for the header of a benchmark table.
std::string BenchMachineDescription();

// Writes `dir/<stem>.gnuplot` (a PNG terminal of width×height, output `<stem>.png`, then `body`)
// and runs gnuplot in `dir`: the script names its data and its picture relative to itself, so a
// copy in docs/benchmarks redraws there. A gnuplot that fails is a warning naming `bench`: the
// table and the data are written by then.
void WritePlot(const std::filesystem::path& dir, const std::string& stem, int width, int height,
               const std::string& body, const std::string& bench);

// `s` as one single-quoted shell word.
std::string ShellQuote(const std::string& s);

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
