#pragma once
// Frame sets for the reconstruction's hard-case tests: street_a's images for a subset of cameras,
// each frame possibly altered, written to a scratch folder and reconstructed from there.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "capture/rig.h"
#include "capture/source.h"
#include "core/error.h"
#include "tracking/evaluation.h"
#include "tracking/reconstruction.h"

namespace odvr::tracking::testing {

inline const std::filesystem::path& StreetDir() {
  static const std::filesystem::path dir = std::filesystem::path(ODVR_SHARED_DIR) / "data/street_a";
  return dir;
}

inline bool HaveStreet() { return std::filesystem::exists(StreetDir() / "rig.json"); }

inline std::string FrameName(long index) {
  char name[32];
  std::snprintf(name, sizeof name, "%06ld.jpg", index);
  return name;
}

// street_a's image of `camera` at frame `index` (BGR, 8 bit).
inline cv::Mat Original(int camera, int index) {
  const cv::Mat m = cv::imread((StreetDir() / "rig" / ("cam" + std::to_string(camera)) / FrameName(index)).string(),
                               cv::IMREAD_COLOR);
  EXPECT_FALSE(m.empty()) << "camera " << camera << " frame " << index;
  return m;
}

// The front three cameras: enough overlap for links, a third of the work.
inline const std::vector<int> kFront = {0, 1, 5};

// A scratch folder per camera; make(camera, index) gives the image of output frame `index`
// (an empty Mat leaves the file out). The rig holds the chosen cameras in the order given.
struct Frames {
  Frames(const std::string& tag, const std::vector<int>& cameras, int count,
         const std::function<cv::Mat(int camera, int index)>& make) {
    namespace fs = std::filesystem;
    dir = fs::temp_directory_path() / ("odvr_hard_" + tag + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    const capture::Rig full = capture::LoadRig(StreetDir() / "rig.json");
    for (int c : cameras) {
      const fs::path cam = dir / full.cameras[c].name;
      fs::create_directories(cam);
      dirs.push_back(cam.string());
      rig.cameras.push_back(full.cameras[c]);
      for (int i = 0; i < count; ++i) {
        const cv::Mat image = make(c, i);
        if (!image.empty()) cv::imwrite((cam / FrameName(i)).string(), image, {cv::IMWRITE_JPEG_QUALITY, 95});
      }
    }
    rig.height_m = full.height_m;
    rig.path = StreetDir() / "rig.json";
  }
  ~Frames() { std::filesystem::remove_all(dir); }
  Frames(const Frames&) = delete;
  Frames& operator=(const Frames&) = delete;

  Reconstruction Run(const ReconstructionOptions& options = {}) const {
    auto source = capture::OpenImageSequences(dirs, {});
    return Reconstruct(rig, *source, options);
  }

  std::filesystem::path dir;
  std::vector<std::string> dirs;
  capture::Rig rig;
};

// Runs `run`, which must throw odvr::Error with every needle in its message.
inline void ExpectError(const std::function<void()>& run, const std::vector<std::string>& needles) {
  try {
    run();
    ADD_FAILURE() << "no error; expected one saying '" << needles.front() << "'";
  } catch (const Error& e) {
    std::cout << "error: " << e.what() << "\n";
    for (const auto& n : needles) EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << e.what();
  }
}

// The trajectory's errors against street_a's ground truth (printed with the stages and warnings);
// every pose must be finite.
inline TrajectoryErrors Evaluate(const Reconstruction& r, bool skip_duplicates = false) {
  std::vector<TrajectoryPose> estimate;
  for (const auto& f : r.frames) {
    EXPECT_TRUE(f.world_from_rig.AllFinite()) << "frame " << f.index;
    if (skip_duplicates && f.duplicate_of >= 0) continue;
    estimate.push_back({f.index, f.timestamp, f.world_from_rig.Matrix()});
  }
  const TrajectoryErrors e = EvaluateTrajectory(estimate, LoadTrajectoryJson(StreetDir() / "trajectory_gt.json"));
  for (const auto& s : r.stages) std::cout << s.name << ": " << s.inliers << " " << s.what << "\n";
  for (const auto& w : r.warnings) std::cout << "warning: " << w << "\n";
  std::cout << e.Summary() << "\n";
  return e;
}

}  // namespace odvr::tracking::testing
