// odvr bench reconstruct (issue 6): our structure from motion (tracking/reconstruction.h) against
// the dataset's ground-truth rig poses, beside COLMAP 3.8 run through its command line on the same
// images on the same machine. ATE after a similarity alignment, RPE and, for our metric
// trajectory, the scale error without aligning scale (tracking/evaluation.h); time per stage.
// Writes a Markdown table, the raw rows (TSV), the per-stage times and the aligned trajectories
// (TSV), and a PNG of the trajectories seen from above.
//
// COLMAP gets what a user with a calibrated rig would give it: one OPENCV_FISHEYE camera per rig
// camera with the known intrinsics, held fixed by the mapper (ours holds them fixed too), CPU
// SIFT, sequential matching with an overlap of three rig frames, no loop detection.
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "app/bench_common.h"
#include "app/commands.h"
#include "capture/rig.h"
#include "capture/source.h"
#include "engine/core/atomic_file.h"
#include "engine/core/error.h"
#include "tracking/evaluation.h"
#include "tracking/reconstruction.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Rig frames the sequential matcher compares each image with: its own frame's other cameras
// and the next two frames' (seconds of video at 25 fps are far more than the 60° between
// neighbouring cameras needs to overlap).
constexpr int kMatchFrames = 3;

struct BenchReconstructOptions {
  std::string dataset = (fs::path(ODVR_SOURCE_DIR) / ".." / "shared" / "data" / "street_a").lexically_normal().string();
  long frames = 0;  // 0: every frame of the dataset
  bool no_colmap = false, colmap_only = false, report_only = false, keep_workspace = false;
  std::string colmap = "colmap";
  std::string out_dir = "docs/benchmarks";
};

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

double RoundTo(double v, double per_unit) { return std::isfinite(v) ? std::round(v * per_unit) / per_unit : v; }
double SecondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string Num(double v, int digits) { return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : "n/a"; }

double ParseNum(const std::string& s, const fs::path& file, int line) {
  if (s == "n/a") return kNaN;
  try {
    std::size_t used = 0;
    const double v = std::stod(s, &used);
    if (used == s.size()) return v;
  } catch (const std::exception&) {
  }
  throw Error(file.string(), fmt::format("line {}: '{}' is not a number", line, s));
}

std::vector<std::vector<std::string>> ReadTsv(const fs::path& path, const std::string& header) {
  std::ifstream in(path);
  if (!in) throw Error(path.string(), "cannot read (run the bench without --report-only first)");
  std::string line;
  if (!std::getline(in, line) || line != header)
    throw Error(path.string(), "line 1: not the header this bench writes (" + header + ")");
  const auto columns = static_cast<std::size_t>(std::count(header.begin(), header.end(), '\t') + 1);
  std::vector<std::vector<std::string>> out;
  for (int n = 2; std::getline(in, line); ++n) {
    std::vector<std::string> f;
    std::stringstream s(line);
    for (std::string field; std::getline(s, field, '\t');) f.push_back(field);
    if (!line.empty() && line.back() == '\t') f.emplace_back();
    if (f.size() != columns)
      throw Error(path.string(), fmt::format("line {}: {} columns, expected {}", n, f.size(), columns));
    out.push_back(std::move(f));
  }
  return out;
}

const char* kRowsHeader =
    "method\tdataset\tframes\tseconds\tframes_posed\tmatched\tpath_length_m\tate_rmse_m\tate_percent\tate_max_m\t"
    "ate_rigid_rmse_m\trpe_translation_m\trpe_rotation_deg\tscale\tscale_error_percent\timages_registered\t"
    "images_total\tpoints\tmachine\tnote";
const char* kStagesHeader = "method\tstage\tseconds\tdetail";
const char* kPathsHeader = "method\tframe\tx\ty\tz";

void WriteResults(const Results& r, const fs::path& dir) {
  std::ostringstream t;
  t << kRowsHeader << "\n";
  for (const auto& m : r.rows)
    t << m.method << "\t" << m.dataset << "\t" << m.frames << "\t" << Num(m.seconds, 2) << "\t" << m.frames_posed
      << "\t" << m.matched << "\t" << Num(m.length_m, 3) << "\t" << Num(m.ate_m, 4) << "\t" << Num(m.ate_percent, 3)
      << "\t" << Num(m.ate_max_m, 4) << "\t" << Num(m.ate_rigid_m, 4) << "\t" << Num(m.rpe_m, 4) << "\t"
      << Num(m.rpe_deg, 3) << "\t" << Num(m.scale, 4) << "\t" << Num(m.scale_error_percent, 2) << "\t"
      << m.images_registered << "\t" << m.images_total << "\t" << m.points << "\t" << m.machine << "\t" << m.note
      << "\n";
  WriteTextAtomically(dir / "tracking.tsv", t.str());
  std::ostringstream s;
  s << kStagesHeader << "\n";
  for (const auto& st : r.stages)
    s << st.method << "\t" << st.stage << "\t" << Num(st.seconds, 2) << "\t" << st.detail << "\n";
  WriteTextAtomically(dir / "tracking_stages.tsv", s.str());
  std::ostringstream p;
  p << kPathsHeader << "\n";
  for (const auto& q : r.paths)
    p << q.method << "\t" << q.frame << "\t"
      << fmt::format("{:.4f}\t{:.4f}\t{:.4f}", q.position.x(), q.position.y(), q.position.z()) << "\n";
  WriteTextAtomically(dir / "tracking_paths.tsv", p.str());
}

Results ReadResults(const fs::path& dir) {
  Results r;
  const fs::path rows = dir / "tracking.tsv", stages = dir / "tracking_stages.tsv", paths = dir / "tracking_paths.tsv";
  int n = 1;
  for (const auto& f : ReadTsv(rows, kRowsHeader)) {
    ++n;
    MethodRow m;
    const auto num = [&](std::size_t i) { return ParseNum(f[i], rows, n); };
    m.method = f[0];
    m.dataset = f[1];
    m.frames = static_cast<long>(num(2));
    m.seconds = num(3);
    m.frames_posed = static_cast<long>(num(4));
    m.matched = static_cast<long>(num(5));
    m.length_m = num(6);
    m.ate_m = num(7);
    m.ate_percent = num(8);
    m.ate_max_m = num(9);
    m.ate_rigid_m = num(10);
    m.rpe_m = num(11);
    m.rpe_deg = num(12);
    m.scale = num(13);
    m.scale_error_percent = num(14);
    m.images_registered = static_cast<long>(num(15));
    m.images_total = static_cast<long>(num(16));
    m.points = static_cast<long>(num(17));
    m.machine = f[18];
    m.note = f[19];
    r.rows.push_back(m);
  }
  n = 1;
  for (const auto& f : ReadTsv(stages, kStagesHeader))
    r.stages.push_back({f[0], f[1], ParseNum(f[2], stages, ++n), f[3]});
  n = 1;
  for (const auto& f : ReadTsv(paths, kPathsHeader)) {
    ++n;
    r.paths.push_back({f[0],
                       static_cast<long>(ParseNum(f[1], paths, n)),
                       {ParseNum(f[2], paths, n), ParseNum(f[3], paths, n), ParseNum(f[4], paths, n)}});
  }
  return r;
}

// Progress of one long stage on stderr, as odvr reconstruct prints it: a line that rewrites
// itself on a terminal, every 10th unit and the last in a log.
class StageProgress {
 public:
  void operator()(const std::string& stage, long done, long total) {
    if (stage != stage_) {
      stage_ = stage;
      start_ = Clock::now();
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
  Clock::time_point start_ = Clock::now();
  bool tty_ = ::isatty(STDERR_FILENO) != 0;
};

// The machine and its load now: other work on a shared machine slows every method.
std::string MachineNow() {
  std::string machine = BenchMachineDescription();
  if (std::ifstream load("/proc/loadavg"); load) {
    double one_minute = 0;
    if (load >> one_minute) machine += fmt::format(", 1-minute load average {:.1f} at its start", one_minute);
  }
  return machine;
}

std::vector<tracking::TrajectoryPose> GroundTruth(const fs::path& dataset) {
  const fs::path path = dataset / "trajectory_gt.json";
  if (!fs::exists(path)) throw UsageError("--dataset", dataset.string() + " has no trajectory_gt.json");
  return tracking::LoadTrajectoryJson(path);
}

// The estimate's positions mapped onto the truth by the similarity ATE is computed after, for
// the plot (frames without ground truth are left out).
void AddAlignedPath(const std::string& method, const std::vector<tracking::TrajectoryPose>& estimate,
                    const std::vector<tracking::TrajectoryPose>& truth, Results* out) {
  std::map<long, Eigen::Vector3d> gt;
  for (const auto& p : truth) gt[p.index] = p.world_from_rig.block<3, 1>(0, 3);
  std::vector<Eigen::Vector3d> src, dst;
  std::vector<long> frames;
  for (const auto& p : estimate)
    if (auto it = gt.find(p.index); it != gt.end()) {
      src.push_back(p.world_from_rig.block<3, 1>(0, 3));
      dst.push_back(it->second);
      frames.push_back(p.index);
    }
  if (src.size() < 3) return;
  const tracking::Similarity3 s = tracking::AlignUmeyama(src, dst, true);
  for (std::size_t i = 0; i < src.size(); ++i)
    out->paths.push_back({method, frames[i], s.scale * (s.rotation * src[i]) + s.translation});
}

void FillErrors(const tracking::TrajectoryErrors& e, MethodRow* m) {
  m->matched = e.matched;
  m->length_m = RoundTo(e.length_m, 1e3);
  m->ate_m = RoundTo(e.ate_rmse_m, 1e4);
  m->ate_percent = RoundTo(e.ate_percent, 1e3);
  m->ate_max_m = RoundTo(e.ate_max_m, 1e4);
  m->ate_rigid_m = RoundTo(e.ate_rigid_rmse_m, 1e4);
  m->rpe_m = RoundTo(e.rpe_translation_rmse_m, 1e4);
  m->rpe_deg = RoundTo(e.rpe_rotation_rmse_deg, 1e3);
  m->scale = RoundTo(e.scale, 1e4);
  m->scale_error_percent = RoundTo(100 * e.scale_error, 1e2);
}

// ---- ours ------------------------------------------------------------------------------------

void RunOurs(const BenchReconstructOptions& o, const capture::Rig& rig, long frames,
             const std::vector<tracking::TrajectoryPose>& truth, Results* out) {
  std::vector<std::string> dirs;
  for (const auto& cam : rig.cameras) dirs.push_back((fs::path(o.dataset) / cam.image_dir).string());
  MethodRow m;
  m.method = "odvr";
  m.machine = MachineNow();
  m.dataset = fs::path(o.dataset).filename().string();
  m.frames = frames;
  m.images_total = frames * rig.camera_count();
  tracking::ReconstructionOptions options;
  options.max_frames = frames;
  StageProgress progress;
  tracking::ReconstructionCallbacks callbacks;
  callbacks.progress = [&](const std::string& stage, int done, int total) {
    progress("odvr " + stage, done, total > 0 ? total : frames);
  };
  const auto t0 = Clock::now();
  try {
    auto source = capture::OpenImageSequences(dirs, {});
    const tracking::Reconstruction r = tracking::Reconstruct(rig, *source, options, callbacks);
    m.seconds = RoundTo(SecondsSince(t0), 1e2);
    progress.Clear();
    std::vector<tracking::TrajectoryPose> estimate;
    for (const auto& f : r.frames) {
      if (!f.world_from_rig.AllFinite()) continue;
      estimate.push_back({f.index, f.timestamp, f.world_from_rig.Matrix()});
    }
    m.frames_posed = static_cast<long>(estimate.size());
    m.images_registered = m.frames_posed * rig.camera_count();
    m.points = static_cast<long>(r.points.size());
    FillErrors(tracking::EvaluateTrajectory(estimate, truth), &m);
    AddAlignedPath("odvr", estimate, truth, out);
    double staged = 0;
    for (const auto& s : r.stages) {
      out->stages.push_back({"odvr", s.name, RoundTo(s.seconds, 1e2), fmt::format("{} {}", s.inliers, s.what)});
      staged += s.seconds;
    }
    out->stages.push_back(
        {"odvr", "other (reading images, setup)", RoundTo(std::max(0.0, m.seconds - staged), 1e2), ""});
    m.note = fmt::format("reprojection RMSE {:.2f} px over {} observations; {} cross-camera links; scale from {}",
                         r.rmse_px, r.observations, r.cross_camera_links, r.scale_source);
    for (const auto& w : r.warnings) m.note += "; warning: " + w;
  } catch (const std::exception& e) {
    // A failure is a result too: the table says so rather than the bench dying without one.
    progress.Clear();
    m.seconds = RoundTo(SecondsSince(t0), 1e2);
    m.note = std::string("failed: ") + e.what();
    spdlog::error("bench reconstruct: odvr failed: {}", e.what());
  }
  for (char& c : m.note)
    if (c == '\t' || c == '\n') c = ' ';
  out->rows.push_back(m);
}

// ---- COLMAP ----------------------------------------------------------------------------------

// The binary as the shell would find it; throws the error the user needs when it is absent.
std::string FindColmap(const std::string& name) {
  const auto executable = [](const fs::path& p) { return fs::is_regular_file(p) && ::access(p.c_str(), X_OK) == 0; };
  if (name.find('/') != std::string::npos) {
    if (executable(name)) return name;
  } else if (const char* path = std::getenv("PATH")) {
    std::stringstream s(path);
    for (std::string dir; std::getline(s, dir, ':');)
      if (!dir.empty() && executable(fs::path(dir) / name)) return (fs::path(dir) / name).string();
  }
  throw Error("--colmap", "'" + name +
                              "' is not an executable on PATH: install COLMAP 3.8 (Debian: apt install colmap), "
                              "pass its path with --colmap, or run with --no-colmap");
}

// Runs one COLMAP command, its output into `log`; `on_line` sees each line (for progress).
// Throws naming the command and quoting the end of its log when it fails.
double RunColmap(const std::string& binary, const std::string& command, const std::vector<std::string>& args,
                 const fs::path& log, const std::function<void(const std::string&)>& on_line) {
  std::string cmd = ShellQuote(binary) + " " + command;
  for (const auto& a : args) cmd += " " + ShellQuote(a);
  cmd += " 2>&1";
  std::ofstream log_file(log, std::ios::app);
  log_file << "$ " << cmd << "\n";
  const auto t0 = Clock::now();
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) throw Error("colmap " + command, "cannot start " + binary);
  std::vector<std::string> tail;
  std::string line;
  for (int ch; (ch = std::fgetc(pipe)) != EOF;) {
    if (ch != '\n' && ch != '\r') {
      line += static_cast<char>(ch);
      continue;
    }
    if (line.empty()) continue;
    log_file << line << "\n";
    if (on_line) on_line(line);
    tail.push_back(line);
    if (tail.size() > 6) tail.erase(tail.begin());
    line.clear();
  }
  const int status = ::pclose(pipe);
  const double seconds = SecondsSince(t0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::string last;
    for (const auto& l : tail) last += "\n  " + l;
    throw Error("colmap " + command, fmt::format("failed (exit status {}; log {}); its last lines:{}",
                                                 WIFEXITED(status) ? WEXITSTATUS(status) : -1, log.string(), last));
  }
  return seconds;
}

// "[12/40]" at the end of COLMAP's "Processed file [12/40]" / "Matching image [12/240]".
bool ParseBracketCount(const std::string& line, const std::string& prefix, long* done, long* total) {
  const auto at = line.find(prefix);
  if (at == std::string::npos) return false;
  return std::sscanf(line.c_str() + at + prefix.size(), " [%ld/%ld]", done, total) == 2;
}

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

// images.txt and points3D.txt of a model converted to text.
ColmapModel ReadColmapText(const fs::path& dir) {
  ColmapModel model;
  const fs::path images = dir / "images.txt";
  std::ifstream in(images);
  if (!in) throw Error(images.string(), "cannot read COLMAP's image list");
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (line.empty() || line[0] == '#') continue;
    // IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, then a line of 2D points (possibly empty).
    long id = 0, camera_id = 0;
    double qw, qx, qy, qz, tx, ty, tz;
    char name[256] = {};
    if (std::sscanf(line.c_str(), "%ld %lf %lf %lf %lf %lf %lf %lf %ld %255s", &id, &qw, &qx, &qy, &qz, &tx, &ty, &tz,
                    &camera_id, name) != 10)
      throw Error(images.string(), fmt::format("line {}: not an image line", n));
    ColmapImage img;
    if (std::sscanf(name, "f%ld_cam%d.jpg", &img.frame, &img.camera) != 2)
      throw Error(images.string(), fmt::format("line {}: image name '{}' is not one this bench wrote", n, name));
    const Eigen::Matrix3d cam_from_world = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    img.world_from_cam_rotation = cam_from_world.transpose();
    img.centre = -(cam_from_world.transpose() * Eigen::Vector3d(tx, ty, tz));
    model.images.push_back(img);
    std::getline(in, line);
    ++n;
  }
  std::ifstream points(dir / "points3D.txt");
  if (!points) throw Error((dir / "points3D.txt").string(), "cannot read COLMAP's points");
  while (std::getline(points, line))
    if (!line.empty() && line[0] != '#') ++model.points;
  return model;
}

// Rig poses from COLMAP's camera poses. COLMAP's world has its own scale, so the rig offsets
// (metres) are first scaled into it: the median ratio of the distances between the centres of a
// frame's registered cameras in COLMAP's world and in the rig. Each registered camera then gives
// a rig pose (world_from_cam * cam_from_rig); a frame's pose is their average (chordal mean
// rotation, mean position), which with every camera registered puts the centre exactly between
// the cameras whatever that scale's error.
std::vector<tracking::TrajectoryPose> ColmapRigPoses(const ColmapModel& model, const capture::Rig& rig,
                                                     double* units_per_metre) {
  std::map<long, std::vector<const ColmapImage*>> by_frame;
  for (const auto& img : model.images)
    if (img.camera >= 0 && img.camera < rig.camera_count()) by_frame[img.frame].push_back(&img);
  std::vector<double> ratios;
  for (const auto& [frame, imgs] : by_frame)
    for (std::size_t a = 0; a < imgs.size(); ++a)
      for (std::size_t b = a + 1; b < imgs.size(); ++b) {
        const double rig_d = (rig.cameras[static_cast<std::size_t>(imgs[a]->camera)].rig_from_cam.block<3, 1>(0, 3) -
                              rig.cameras[static_cast<std::size_t>(imgs[b]->camera)].rig_from_cam.block<3, 1>(0, 3))
                                 .norm();
        if (rig_d > 1e-6) ratios.push_back((imgs[a]->centre - imgs[b]->centre).norm() / rig_d);
      }
  const double s = ratios.empty() ? 1.0 : Median(ratios);
  *units_per_metre = ratios.empty() ? kNaN : s;
  std::vector<tracking::TrajectoryPose> poses;
  for (const auto& [frame, imgs] : by_frame) {
    Eigen::Matrix3d rotation_sum = Eigen::Matrix3d::Zero();
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    for (const ColmapImage* img : imgs) {
      const Eigen::Matrix4d& rig_from_cam = rig.cameras[static_cast<std::size_t>(img->camera)].rig_from_cam;
      const Eigen::Matrix3d cam_from_rig_r = rig_from_cam.block<3, 3>(0, 0).transpose();
      const Eigen::Vector3d cam_from_rig_t = -(cam_from_rig_r * rig_from_cam.block<3, 1>(0, 3)) * s;
      rotation_sum += img->world_from_cam_rotation * cam_from_rig_r;
      position += img->world_from_cam_rotation * cam_from_rig_t + img->centre;
    }
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(rotation_sum, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
    if (r.determinant() < 0) {
      Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
      d(2, 2) = -1;
      r = svd.matrixU() * d * svd.matrixV().transpose();
    }
    tracking::TrajectoryPose p;
    p.index = frame;
    p.world_from_rig.block<3, 3>(0, 0) = r;
    p.world_from_rig.block<3, 1>(0, 3) = position / static_cast<double>(imgs.size());
    poses.push_back(p);
  }
  return poses;
}

void RunColmapBench(const BenchReconstructOptions& o, const capture::Rig& rig, long frames,
                    const std::vector<tracking::TrajectoryPose>& truth, Results* out, BenchProgress* overall) {
  const std::string binary = FindColmap(o.colmap);
  for (const auto& cam : rig.cameras)
    if (cam.model.type() != capture::CameraModelType::kFisheye)
      throw Error(rig.path.string(),
                  "camera " + cam.name + " is not a fisheye; this bench gives COLMAP OPENCV_FISHEYE");
  const fs::path ws = fs::temp_directory_path() / fmt::format("odvr_bench_colmap_{}", ::getpid());
  fs::remove_all(ws);
  fs::create_directories(ws / "images");
  fs::create_directories(ws / "sparse");
  const fs::path log = ws / "colmap.log";
  struct Cleanup {
    fs::path dir;
    bool keep;
    ~Cleanup() {
      std::error_code ec;
      if (!keep) fs::remove_all(dir, ec);
    }
  } cleanup{ws, o.keep_workspace};
  if (o.keep_workspace) spdlog::info("bench reconstruct: COLMAP workspace {}", ws.string());

  // Flat names that sort frame-major (f000012_cam3.jpg): the sequential matcher orders images by
  // name, so a rig frame's cameras and the next frames' come next to each other. (Per-camera
  // folders with single_camera_per_folder would sort camera-major and never match across
  // cameras.) One extraction per rig camera with single_camera gives each its own camera.
  const int cams = rig.camera_count();
  for (int c = 0; c < cams; ++c) {
    std::ofstream list(ws / fmt::format("list{}.txt", c));
    for (long f = 0; f < frames; ++f) {
      const std::string name = fmt::format("f{:06d}_cam{}.jpg", f, c);
      const fs::path src = fs::absolute(fs::path(o.dataset) / rig.cameras[static_cast<std::size_t>(c)].image_dir /
                                        fmt::format("{:06d}.jpg", f));
      if (!fs::exists(src)) throw Error(src.string(), "missing rig image");
      fs::create_symlink(src, ws / "images" / name);
      list << name << "\n";
    }
  }
  MethodRow m;
  m.method = "colmap";
  m.machine = MachineNow();
  m.dataset = fs::path(o.dataset).filename().string();
  m.frames = frames;
  m.images_total = frames * cams;
  StageProgress progress;
  const std::string db = (ws / "database.db").string(), images = (ws / "images").string();

  // COLMAP's OPENCV_FISHEYE is the same Kannala-Brandt polynomial; its pixel centres sit at +0.5.
  double extract_s = 0;
  long extracted = 0;
  for (int c = 0; c < cams; ++c) {
    const auto& k = rig.cameras[static_cast<std::size_t>(c)].model;
    const auto& d = k.distortion();
    const std::string params = fmt::format(
        "{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}", k.fx(), k.fy(), k.cx() + 0.5, k.cy() + 0.5,
        d.size() > 0 ? d[0] : 0.0, d.size() > 1 ? d[1] : 0.0, d.size() > 2 ? d[2] : 0.0, d.size() > 3 ? d[3] : 0.0);
    extract_s += RunColmap(binary, "feature_extractor",
                           {"--database_path", db, "--image_path", images, "--image_list_path",
                            (ws / fmt::format("list{}.txt", c)).string(), "--ImageReader.camera_model",
                            "OPENCV_FISHEYE", "--ImageReader.single_camera", "1", "--ImageReader.camera_params", params,
                            "--SiftExtraction.use_gpu", "0", "--SiftExtraction.num_threads", "-1"},
                           log, [&](const std::string& line) {
                             long done = 0, total = 0;
                             if (ParseBracketCount(line, "Processed file", &done, &total))
                               progress("colmap feature_extractor", extracted + done, frames * cams);
                           });
    extracted += frames;
  }
  progress.Clear();
  out->stages.push_back({"colmap", "feature_extractor", RoundTo(extract_s, 1e2),
                         fmt::format("CPU SIFT, {} images, one OPENCV_FISHEYE camera per rig camera", frames * cams)});
  overall->Step("COLMAP features");

  const int overlap = kMatchFrames * cams;
  const double match_s =
      RunColmap(binary, "sequential_matcher",
                {"--database_path", db, "--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads", "-1",
                 "--SequentialMatching.overlap", std::to_string(overlap), "--SequentialMatching.quadratic_overlap", "0",
                 "--SequentialMatching.loop_detection", "0"},
                log, [&](const std::string& line) {
                  long done = 0, total = 0;
                  if (ParseBracketCount(line, "Matching image", &done, &total))
                    progress("colmap sequential_matcher", done, total);
                });
  progress.Clear();
  out->stages.push_back({"colmap", "sequential_matcher", RoundTo(match_s, 1e2),
                         fmt::format("CPU, overlap {} images ({} rig frames), no quadratic overlap, no loop detection",
                                     overlap, kMatchFrames)});
  overall->Step("COLMAP matching");

  long registered_now = 0;
  const double map_s =
      RunColmap(binary, "mapper",
                {"--database_path", db, "--image_path", images, "--output_path", (ws / "sparse").string(),
                 "--Mapper.num_threads", "-1", "--Mapper.ba_refine_focal_length", "0",
                 "--Mapper.ba_refine_principal_point", "0", "--Mapper.ba_refine_extra_params", "0"},
                log, [&](const std::string& line) {
                  // "Registering image #17 (5)": the count in brackets is the model's registered images.
                  long id = 0, count = 0;
                  const auto at = line.find("Registering image #");
                  if (at != std::string::npos &&
                      std::sscanf(line.c_str() + at, "Registering image #%ld (%ld)", &id, &count) == 2) {
                    registered_now = std::max(registered_now, count);
                    progress("colmap mapper (images registered)", registered_now, frames * cams);
                  }
                });
  progress.Clear();
  overall->Step("COLMAP mapper");

  // Every model to text; the largest (most registered images) is the one scored.
  double convert_s = 0;
  std::optional<ColmapModel> best;
  std::vector<std::size_t> sizes;
  for (const auto& entry : fs::directory_iterator(ws / "sparse")) {
    if (!entry.is_directory()) continue;
    const fs::path txt = ws / ("txt_" + entry.path().filename().string());
    fs::create_directories(txt);
    convert_s += RunColmap(
        binary, "model_converter",
        {"--input_path", entry.path().string(), "--output_path", txt.string(), "--output_type", "TXT"}, log, nullptr);
    ColmapModel model = ReadColmapText(txt);
    sizes.push_back(model.images.size());
    if (!best || model.images.size() > best->images.size()) best = std::move(model);
  }
  std::sort(sizes.rbegin(), sizes.rend());
  out->stages.push_back(
      {"colmap", "mapper", RoundTo(map_s, 1e2), fmt::format("CPU, intrinsics fixed, {} model(s)", sizes.size())});
  out->stages.push_back({"colmap", "model_converter", RoundTo(convert_s, 1e2), "binary to text"});
  m.seconds = RoundTo(extract_s + match_s + map_s + convert_s, 1e2);
  overall->Step("COLMAP model");
  if (!best || best->images.empty()) {
    m.note = "failed: the mapper made no model";
    out->rows.push_back(m);
    return;
  }
  m.images_registered = static_cast<long>(best->images.size());
  m.points = best->points;
  double units_per_metre = kNaN;
  std::vector<tracking::TrajectoryPose> estimate = ColmapRigPoses(*best, rig, &units_per_metre);
  m.frames_posed = static_cast<long>(estimate.size());
  std::string models;
  for (std::size_t s : sizes) models += (models.empty() ? "" : ", ") + std::to_string(s);
  m.note = fmt::format("{} model(s) of {} images; rig offsets scaled by {} COLMAP units per metre", sizes.size(),
                       models, Num(units_per_metre, 3));
  try {
    // COLMAP's scale is arbitrary: put its trajectory into metres by the similarity alignment
    // first, so its RPE is in metres too; ATE is unchanged by this, its scale error means nothing.
    std::map<long, Eigen::Vector3d> gt;
    for (const auto& p : truth) gt[p.index] = p.world_from_rig.block<3, 1>(0, 3);
    std::vector<Eigen::Vector3d> src, dst;
    for (const auto& p : estimate)
      if (auto it = gt.find(p.index); it != gt.end()) {
        src.push_back(p.world_from_rig.block<3, 1>(0, 3));
        dst.push_back(it->second);
      }
    const tracking::Similarity3 sim = tracking::AlignUmeyama(src, dst, true);
    for (auto& p : estimate) {
      p.world_from_rig.block<3, 3>(0, 0) = sim.rotation * p.world_from_rig.block<3, 3>(0, 0);
      p.world_from_rig.block<3, 1>(0, 3) =
          sim.scale * (sim.rotation * p.world_from_rig.block<3, 1>(0, 3)) + sim.translation;
    }
    FillErrors(tracking::EvaluateTrajectory(estimate, truth), &m);
    m.scale = m.scale_error_percent = m.ate_rigid_m = kNaN;
    AddAlignedPath("colmap", estimate, truth, out);
  } catch (const Error& e) {
    m.note += std::string("; not scored: ") + e.what();
  }
  out->rows.push_back(m);
}

// ---- report ----------------------------------------------------------------------------------

const MethodRow* Find(const Results& r, const std::string& method) {
  for (const auto& m : r.rows)
    if (m.method == method) return &m;
  return nullptr;
}

std::string Targets(const Results& r) {
  const MethodRow* ours = Find(r, "odvr");
  const MethodRow* colmap = Find(r, "colmap");
  std::ostringstream md;
  md << "\n## Targets (issue 6), from the rows above\n\n";
  const auto verdict = [](bool met) { return met ? "met" : "not met"; };
  if (!ours || !std::isfinite(ours->ate_percent)) {
    md << "**Not measured:** odvr has no trajectory in this table" << (ours ? " (" + ours->note + ")" : "") << ".\n";
    return md.str();
  }
  const bool ate_ok = ours->ate_percent <= 1.0;
  md << "- **ATE ≤ 1 % of the trajectory length: " << verdict(ate_ok) << ".** odvr's ATE is " << Num(ours->ate_m, 4)
     << " m = " << Num(ours->ate_percent, 3) << " % of the " << Num(ours->length_m, 2) << " m path (" << ours->matched
     << " frames).\n";
  if (colmap && std::isfinite(colmap->ate_m)) {
    const bool below = ours->ate_m < colmap->ate_m;
    md << "- **ATE below COLMAP's on the same sequence: " << verdict(below) << ".** " << Num(ours->ate_m, 4)
       << " m against " << Num(colmap->ate_m, 4) << " m (" << fmt::format("{:.2f}", ours->ate_m / colmap->ate_m)
       << "×)";
    if (colmap->matched != ours->matched)
      md << "; COLMAP's figure is over the " << colmap->matched << " frames it posed, odvr's over " << ours->matched;
    md << ".\n";
    const bool faster = ours->seconds < colmap->seconds;
    md << "- **In less time than COLMAP: " << verdict(faster) << ".** " << Num(ours->seconds, 1) << " s against "
       << Num(colmap->seconds, 1) << " s ("
       << (faster ? fmt::format("{:.1f}× faster", colmap->seconds / ours->seconds)
                  : fmt::format("{:.1f}× slower", ours->seconds / colmap->seconds))
       << ").\n";
  } else {
    md << "- **ATE below COLMAP's, in less time: not measured**"
       << (colmap ? " (COLMAP: " + colmap->note + ")" : " (run without --no-colmap)") << ".\n";
  }
  const bool scale_ok = ours->scale_error_percent <= 3.0;
  md << "- **Metric scale within 3 % of the truth: " << verdict(scale_ok) << ".** The metric trajectory is "
     << Num(ours->scale, 4) << "× the true length (" << Num(ours->scale_error_percent, 2)
     << " % off), with no scale aligned; its ATE after a rigid alignment alone is " << Num(ours->ate_rigid_m, 4)
     << " m.\n";
  return md.str();
}

void WriteReport(const Results& r, const BenchReconstructOptions& o) {
  const fs::path dir = o.out_dir;
  fs::create_directories(dir);
  WriteResults(r, dir);
  const MethodRow* any = r.rows.empty() ? nullptr : &r.rows.front();
  const long cameras = any && any->frames > 0 ? any->images_total / any->frames : 6;
  std::ostringstream md;
  md << "# Tracking: the rig's trajectory against the ground truth, beside COLMAP\n\n"
     << "Made by `odvr bench reconstruct`";
  std::vector<std::string> machines;
  for (const auto& m : r.rows)
    if (std::find(machines.begin(), machines.end(), m.machine) == machines.end()) machines.push_back(m.machine);
  if (machines.size() == 1) {
    md << " on " << machines[0];
  } else {
    for (const auto& m : r.rows) md << (&m == &r.rows.front() ? "; " : ", ") << m.method << " on " << m.machine;
  }
  md << ". Dataset `" << (any ? any->dataset : "?") << "`, " << (any ? any->frames : 0) << " rig frames of " << cameras
     << " cameras (street_*: 480×640 equidistant fisheyes, 120°×160° each, 60° apart, 25 fps). Errors are "
        "against `trajectory_gt.json` (the rig centre's pose per frame), computed by tracking/evaluation.h:\n\n"
     << "- **ATE**: RMSE of the rig positions after the similarity (Umeyama) alignment that best maps the "
        "estimate onto the truth; also as % of the true path length over the frames scored.\n"
     << "- **RPE**: RMSE of the error of each frame-to-frame motion (translation in metres, rotation in degrees).\n"
     << "- **Scale error**: how much longer or shorter the metric trajectory is than the truth, with no scale "
        "aligned (the one error a similarity alignment hides). COLMAP has no metric scale: its trajectory is "
        "brought into metres by the similarity alignment before its RPE is computed, and its scale error is n/a.\n\n"
     << "Methods (both on all cores, on the same JPEGs; the time is wall-clock, from the images on disk to the "
        "poses):\n\n"
     << "- `odvr`: tracking::Reconstruct with its default options: per-camera KLT tracks, cross-camera SIFT "
        "links, non-central relative and absolute pose, Ceres bundle adjustment of the rig poses with the "
        "calibration fixed, metric scale from the road plane and the rig height in rig.json.\n"
     << "- `colmap`: COLMAP 3.8 (Debian, no CUDA) through its command line: `feature_extractor` (CPU SIFT, one "
        "OPENCV_FISHEYE camera per rig camera with the known intrinsics, k1..k4 = 0, principal point +0.5 px for "
        "COLMAP's pixel-corner origin), `sequential_matcher` (CPU; each image against the next "
     << kMatchFrames * cameras << " in frame-major order: the rest of its rig frame and the next " << kMatchFrames - 1
     << "; no quadratic overlap, no loop detection), `mapper` (CPU; intrinsics held fixed, as odvr holds them; the "
        "largest model is scored), `model_converter` to text. COLMAP knows nothing of the rig: each frame's rig "
        "pose is the average of the poses its registered cameras imply through T_rig_cam (the 0.08 m offsets "
        "scaled into COLMAP's units by the median ratio of the camera spacings). OPENCV_FISHEYE models angles "
        "below 90° only; the image corners reach 100°, so features there are lost or wrong for COLMAP, not for "
        "odvr.\n\n"
     << "| method | seconds | frames posed | images registered | points | ATE (m) | ATE (% of path) | ATE max (m) | "
        "RPE (m) | RPE (°) | scale error |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& m : r.rows)
    md << "| " << m.method << " | " << Num(m.seconds, 1) << " | " << m.frames_posed << "/" << m.frames << " | "
       << m.images_registered << "/" << m.images_total << " | " << m.points << " | " << Num(m.ate_m, 4) << " | "
       << Num(m.ate_percent, 3) << " | " << Num(m.ate_max_m, 4) << " | " << Num(m.rpe_m, 4) << " | "
       << Num(m.rpe_deg, 3) << " | "
       << (std::isfinite(m.scale_error_percent) ? Num(m.scale_error_percent, 2) + " %" : std::string("n/a")) << " |\n";
  md << "\n";
  for (const auto& m : r.rows)
    if (!m.note.empty()) md << "- `" << m.method << "`: " << m.note << ".\n";
  md << "\nTime per stage (seconds):\n\n| method | stage | seconds | |\n|---|---|---|---|\n";
  for (const auto& s : r.stages)
    md << "| " << s.method << " | " << s.stage << " | " << Num(s.seconds, 2) << " | " << s.detail << " |\n";
  md << Targets(r)
     << "\nEvery figure is in `tracking.tsv` (per-stage times in `tracking_stages.tsv`, the aligned positions in "
        "`tracking_paths.tsv`). The plot shows the trajectories from above in the ground truth's world, each "
        "estimate after the similarity alignment its ATE is computed with; below, each frame's position error after "
        "that alignment (log scale).\n\n"
        "![Trajectories seen from above](tracking.png)\n";
  WriteTextAtomically(dir / "tracking.md", md.str());

  std::ostringstream gp;
  const std::string paths = "tracking_paths.tsv";
  std::vector<std::string> methods;
  for (const auto& p : r.paths)
    if (p.method != "ground truth" && std::find(methods.begin(), methods.end(), p.method) == methods.end())
      methods.push_back(p.method);
  // Below the map, each estimate's distance to the truth per frame: at the map's scale errors of
  // centimetres vanish under the line. A gnuplot data block, derived from the paths TSV.
  std::map<long, Eigen::Vector3d> gt;
  for (const auto& p : r.paths)
    if (p.method == "ground truth") gt[p.frame] = p.position;
  gp << "$errors << EOD\n";
  for (const auto& p : r.paths)
    if (auto it = gt.find(p.frame); p.method != "ground truth" && it != gt.end())
      gp << p.method << "\t" << p.frame << "\t" << fmt::format("{:.2f}", 1000 * (p.position - it->second).norm())
         << "\n";
  gp << "EOD\n"
     << "set datafile separator '\\t'\nset multiplot layout 2,1\nset key outside right\nset grid\n"
     << "set size ratio -1\nset title 'rig trajectory seen from above (ground-truth world, estimates "
        "similarity-aligned)'\nset xlabel 'x (m)'\nset ylabel 'y (m)'\nplot '"
     << paths
     << "' using (strcol(1) eq 'ground truth' ? $3 : 1/0):4 with lines lw 5 lc rgb '#aaaaaa' title 'ground truth'";
  int colour = 1;
  for (const auto& m : methods)
    gp << ", '" << paths << "' using (strcol(1) eq '" << m << "' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc "
       << colour++ << " title '" << m << "'";
  gp << "\nset size noratio\nset title 'position error after the alignment'\nset xlabel 'frame'\n"
        "set ylabel 'mm'\nset logscale y\nplot ";
  colour = 1;
  for (const auto& m : methods) {
    if (colour > 1) gp << ", ";
    gp << "$errors using (strcol(1) eq '" << m
       << "' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc " << colour++ << " title '" << m
       << "'";
  }
  if (methods.empty()) gp << "0 notitle";
  gp << "\nunset multiplot\n";
  WritePlot(dir, "tracking", 1000, 900, gp.str(), "bench reconstruct");
}

int RunBenchReconstruct(const BenchReconstructOptions& o) {
  if (o.no_colmap && o.colmap_only) throw UsageError("--no-colmap", "contradicts --colmap-only");
  if (o.frames < 0 || (o.frames > 0 && o.frames < 3)) throw UsageError("--frames", "needs at least 3 frames (0: all)");
  if (o.report_only) {
    Results r = ReadResults(o.out_dir);
    WriteReport(r, o);
    std::cout << "bench reconstruct: rewrote " << o.out_dir << "/tracking.md and tracking.png from the TSVs\n";
    return 0;
  }
  const fs::path dataset = o.dataset;
  if (!fs::exists(dataset / "rig.json"))
    throw UsageError("--dataset", dataset.string() + " has no rig.json (is ../shared/data present?)");
  const capture::Rig rig = capture::LoadRig(dataset / "rig.json");
  const auto truth = GroundTruth(dataset);
  // Frames: the ground truth's, as many as asked for.
  long frames = static_cast<long>(truth.size());
  if (o.frames > 0) {
    if (o.frames > frames)
      throw UsageError("--frames", fmt::format("{} has {} frames of ground truth, fewer than {}", dataset.string(),
                                               frames, o.frames));
    frames = o.frames;
  }
  const bool run_colmap = !o.no_colmap, run_ours = !o.colmap_only;
  if (run_colmap) FindColmap(o.colmap);  // before minutes of our own run

  Results results;
  const std::string name = dataset.filename().string();
  // Rows of the method not run now are kept from the last run on the same frames.
  if (!run_colmap || !run_ours) {
    std::error_code ec;
    std::optional<Results> old_results;
    if (fs::exists(fs::path(o.out_dir) / "tracking.tsv", ec)) try {
        old_results = ReadResults(o.out_dir);
      } catch (const Error& e) {
        spdlog::warn("bench reconstruct: the last table is not kept: {}", e.what());
      }
    if (old_results) {
      const Results& old = *old_results;
      const std::string kept = run_ours ? "colmap" : "odvr";
      for (const auto& m : old.rows)
        if (m.method == kept && m.dataset == name && m.frames == frames) {
          results.rows.push_back(m);
          for (const auto& s : old.stages)
            if (s.method == kept) results.stages.push_back(s);
          for (const auto& p : old.paths)
            if (p.method == kept) results.paths.push_back(p);
        }
    }
  }
  for (const auto& p : truth)
    if (p.index < frames) results.paths.push_back({"ground truth", p.index, p.world_from_rig.block<3, 1>(0, 3)});

  BenchProgress overall("bench reconstruct", (run_ours ? 1 : 0) + (run_colmap ? 4 : 0));
  if (run_ours) {
    RunOurs(o, rig, frames, truth, &results);
    overall.Step("odvr reconstruct");
  }
  if (run_colmap) RunColmapBench(o, rig, frames, truth, &results, &overall);
  std::stable_sort(results.rows.begin(), results.rows.end(),
                   [](const MethodRow& a, const MethodRow& b) { return a.method > b.method; });  // odvr first
  std::stable_sort(results.stages.begin(), results.stages.end(),
                   [](const StageRow& a, const StageRow& b) { return a.method > b.method; });
  WriteReport(results, o);
  for (const auto& m : results.rows)
    std::cout << fmt::format("{}: {} s, {}/{} frames posed, ATE {} m ({} %), RPE {} m / {} deg, scale error {} %\n",
                             m.method, Num(m.seconds, 1), m.frames_posed, m.frames, Num(m.ate_m, 4),
                             Num(m.ate_percent, 3), Num(m.rpe_m, 4), Num(m.rpe_deg, 3), Num(m.scale_error_percent, 2));
  std::cout << "bench reconstruct: wrote " << o.out_dir << "/tracking.md, tracking.tsv, tracking.png\n";
  return 0;
}

}  // namespace

CommandFn AddBenchReconstruct(CLI::App* sub) {
  auto o = std::make_shared<BenchReconstructOptions>();
  sub->add_option("--dataset", o->dataset, "A street_* dataset (rig.json, rig/, trajectory_gt.json)")
      ->capture_default_str();
  sub->add_option("--frames", o->frames, "Rig frames from the first (0: all the ground truth has)")
      ->capture_default_str();
  sub->add_flag("--no-colmap", o->no_colmap,
                "Run odvr only (COLMAP's rows from the last run on the same frames are kept)");
  sub->add_flag("--colmap-only", o->colmap_only, "Run COLMAP only (odvr's rows from the last run are kept)");
  sub->add_flag("--report-only", o->report_only, "Rewrite the table and plot from the TSVs in --out");
  sub->add_option("--colmap", o->colmap, "The COLMAP binary")->capture_default_str();
  sub->add_flag("--keep-workspace", o->keep_workspace, "Keep COLMAP's temporary workspace (database, models, log)");
  sub->add_option("--out", o->out_dir, "Where the table, TSVs and plot go")->capture_default_str();
  return [o] { return RunBenchReconstruct(*o); };
}

}  // namespace odvr::app
