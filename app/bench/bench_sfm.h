#pragma once
// What `odvr bench reconstruct` (the rig) and `odvr bench reconstruct --equirect` (one 360°
// camera) share: a method's result row and its TSVs, scoring a trajectory against the ground
// truth, progress on stderr, and COLMAP run through its command line and read back.
#include <unistd.h>

#include <Eigen/Core>
#include <chrono>
#include <filesystem>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/fmt/fmt.h>

#include "app/bench/bench_common.h"
#include "capture/rig.h"
#include "capture/source.h"
#include "core/timing.h"
#include "tracking/evaluation.h"
#include "tracking/reconstruction.h"

namespace odvr::app {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// One method's result: a row of tracking.tsv. NaN prints as "n/a".
struct MethodRow {
  std::string method;  // "odvr" or "colmap"
  std::string dataset;
  long frames = 0;  // rig frames given to the method
  double seconds = kNaN;
  long frames_posed = 0;  // rig frames the method gave a pose
  long matched = 0;       // of those, frames with ground truth (what the errors are over)
  double length_m = kNaN, ate_m = kNaN, ate_percent = kNaN, ate_max_m = kNaN, ate_rigid_m = kNaN;
  double rpe_m = kNaN, rpe_deg = kNaN, scale = kNaN, scale_error_percent = kNaN;
  long images_registered = 0, images_total = 0, points = 0;
  std::string machine;  // and its load when the method started: times on a shared machine need it
  std::string note;
};

struct StageRow {
  std::string method, stage;
  double seconds = 0;
  std::string detail;
};

struct PathRow {
  std::string method;  // "ground truth", "odvr", "colmap"
  long frame = 0;
  Eigen::Vector3d position;  // ground-truth world (z up), estimates after the similarity alignment
};

struct Results {
  std::vector<MethodRow> rows;
  std::vector<StageRow> stages;
  std::vector<PathRow> paths;
};

double RoundTo(double v, double per_unit);
std::string Num(double v, int digits);  // "n/a" for NaN

// <stem>.tsv (rows), <stem>_stages.tsv, <stem>_paths.tsv in `dir`, atomically; and back.
void WriteResults(const Results& r, const std::filesystem::path& dir, const std::string& stem);
Results ReadResults(const std::filesystem::path& dir, const std::string& stem);

// The machine and its load now: other work on a shared machine slows every method.
std::string MachineNow();

// The estimate's positions mapped onto the truth by the similarity ATE is computed after, for
// the plot (frames without ground truth are left out).
void AddAlignedPath(const std::string& method, const std::vector<tracking::TrajectoryPose>& estimate,
                    const std::vector<tracking::TrajectoryPose>& truth, Results* out);
void FillErrors(const tracking::TrajectoryErrors& e, MethodRow* m);

// One run of odvr's structure from motion, scored against the truth: a row of `out`, its stages
// and its aligned path. A failure is a row too, its note saying why.
struct OdvrRun {
  std::string method, dataset;
  long frames = 0;  // frame sets read (0: all)
  capture::Rig rig;
  std::function<std::unique_ptr<capture::Source>()> open;  // the frames, opened inside the timing
  tracking::ReconstructionOptions options;                 // max_frames is set from `frames`
  bool metric = true;  // false: up to scale, whose scale error, rigid ATE and RPE in metres mean nothing
};
void RunOdvrReconstruction(const OdvrRun& run, const std::vector<tracking::TrajectoryPose>& truth, Results* out);

// The trajectories from above (ground truth and each method after its similarity alignment) and
// each frame's position error below: <stem>.png from <stem>_paths.tsv, by gnuplot.
void WriteTrajectoryPlot(const Results& r, const std::filesystem::path& dir, const std::string& stem,
                         const std::string& bench);

// COLMAP through its command line.
std::string FindColmap(const std::string& name);
double RunColmap(const std::string& binary, const std::string& command, const std::vector<std::string>& args,
                 const std::filesystem::path& log, const std::function<void(const std::string&)>& on_line);
bool ParseBracketCount(const std::string& line, const std::string& prefix, long* done, long* total);

struct ColmapImage {
  long frame = 0;
  int camera = 0;
  Eigen::Matrix3d world_from_cam_rotation;
  Eigen::Vector3d centre;
};

struct ColmapModel {
  std::vector<ColmapImage> images;
  long points = 0;
};

// images.txt and points3D.txt of a model converted to text; image names f<frame>_cam<camera>.jpg.
ColmapModel ReadColmapText(const std::filesystem::path& dir);
// Rig poses from COLMAP's camera poses (see the definition).
std::vector<tracking::TrajectoryPose> ColmapRigPoses(const ColmapModel& model, const capture::Rig& rig,
                                                     double* units_per_metre);

// A scratch folder for one COLMAP run (images/, sparse/, colmap.log), removed at the end unless
// kept.
struct ColmapWorkspace {
  ColmapWorkspace(const std::string& prefix, bool keep);
  ~ColmapWorkspace();
  ColmapWorkspace(const ColmapWorkspace&) = delete;
  ColmapWorkspace& operator=(const ColmapWorkspace&) = delete;
  std::filesystem::path dir;
  bool keep = false;
};

// One COLMAP reconstruction of images already in a workspace's images/ (named
// f<frame>_cam<camera>.jpg): feature extraction per camera list, sequential matching, the mapper
// with the intrinsics fixed, the largest model scored against the truth as a rig of `rig`'s
// cameras (a row of `out`, its stages and aligned path).
struct ColmapJob {
  std::string binary, method, dataset;
  long frames = 0, images = 0;
  struct Extraction {
    std::filesystem::path list;  // image names, one a line
    std::string camera_model, params;
    long images = 0;
  };
  std::vector<Extraction> extractions;  // one camera each (single_camera)
  int overlap = 0;                      // images the sequential matcher pairs each image with
  std::string overlap_what, camera_what;
};
void RunColmapJob(const ColmapJob& job, const ColmapWorkspace& ws, const capture::Rig& rig,
                  const std::vector<tracking::TrajectoryPose>& truth, Results* out, BenchProgress* overall);

// Progress of one long stage on stderr, as odvr reconstruct prints it: a line that rewrites
// itself on a terminal, every 10th unit and the last in a log.
class StageProgress {
 public:
  void operator()(const std::string& stage, long done, long total) {
    if (stage != stage_) {
      stage_ = stage;
      start_ = std::chrono::steady_clock::now();
    }
    if (total <= 0) return;
    const double in_stage = SecondsSince(start_);
    const double eta =
        done > 0 && total > done ? in_stage / static_cast<double>(done) * static_cast<double>(total - done) : 0.0;
    const std::string line = fmt::format("  {} {}/{}, {:.0f} s, stage ETA {:.0f} s", stage, done, total, in_stage, eta);
    if (tty_)
      std::cerr << "\r\033[K" << line << std::flush;
    else if (done % 10 == 0 || done == total)
      std::cerr << line << "\n";
  }
  void Clear() const {
    if (tty_) std::cerr << "\r\033[K" << std::flush;
  }

 private:
  std::string stage_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  bool tty_ = ::isatty(STDERR_FILENO) != 0;
};

// odvr bench reconstruct --equirect (app/bench/bench_reconstruct_equirect.cpp).
struct EquirectBenchOptions {
  std::string dataset, colmap = "colmap", out_dir;
  long frames = 0;  // 0: every frame of the ground truth
  bool no_colmap = false, keep_workspace = false;
  int crf = 23;            // H.264 quality of the videos made
  int width = 1024;        // tracking width (and the stitched panorama's)
  long clip_frames = 60;   // frames of each real clip
  long long_frames = 600;  // the long clip's length (0: no long clip); also run at a third of it
};
int RunBenchReconstructEquirect(const EquirectBenchOptions& o);

}  // namespace odvr::app
