// The pieces `odvr bench reconstruct` and its one-camera mode share: result rows and their TSVs,
// trajectory scoring, progress, and COLMAP run through its command line and read back.
#include "app/bench/bench_sfm.h"

#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>

#include "app/bench/bench_common.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/timing.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

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

}  // namespace

double RoundTo(double v, double per_unit) { return std::isfinite(v) ? std::round(v * per_unit) / per_unit : v; }

std::string Num(double v, int digits) { return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : "n/a"; }

void WriteResults(const Results& r, const fs::path& dir, const std::string& stem) {
  std::ostringstream t;
  t << kRowsHeader << "\n";
  for (const auto& m : r.rows)
    t << m.method << "\t" << m.dataset << "\t" << m.frames << "\t" << Num(m.seconds, 2) << "\t" << m.frames_posed
      << "\t" << m.matched << "\t" << Num(m.length_m, 3) << "\t" << Num(m.ate_m, 4) << "\t" << Num(m.ate_percent, 3)
      << "\t" << Num(m.ate_max_m, 4) << "\t" << Num(m.ate_rigid_m, 4) << "\t" << Num(m.rpe_m, 4) << "\t"
      << Num(m.rpe_deg, 3) << "\t" << Num(m.scale, 4) << "\t" << Num(m.scale_error_percent, 2) << "\t"
      << m.images_registered << "\t" << m.images_total << "\t" << m.points << "\t" << m.machine << "\t" << m.note
      << "\n";
  WriteTextAtomically(dir / (stem + ".tsv"), t.str());
  std::ostringstream s;
  s << kStagesHeader << "\n";
  for (const auto& st : r.stages)
    s << st.method << "\t" << st.stage << "\t" << Num(st.seconds, 2) << "\t" << st.detail << "\n";
  WriteTextAtomically(dir / (stem + "_stages.tsv"), s.str());
  std::ostringstream p;
  p << kPathsHeader << "\n";
  for (const auto& q : r.paths)
    p << q.method << "\t" << q.frame << "\t"
      << fmt::format("{:.4f}\t{:.4f}\t{:.4f}", q.position.x(), q.position.y(), q.position.z()) << "\n";
  WriteTextAtomically(dir / (stem + "_paths.tsv"), p.str());
}

Results ReadResults(const fs::path& dir, const std::string& stem) {
  Results r;
  const fs::path rows = dir / (stem + ".tsv"), stages = dir / (stem + "_stages.tsv"),
                 paths = dir / (stem + "_paths.tsv");
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

// The machine and its load now: other work on a shared machine slows every method.
std::string MachineNow() {
  std::string machine = BenchMachineDescription();
  if (std::ifstream load("/proc/loadavg"); load) {
    double one_minute = 0;
    if (load >> one_minute) machine += fmt::format(", 1-minute load average {:.1f} at its start", one_minute);
  }
  return machine;
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

ColmapWorkspace::ColmapWorkspace(const std::string& prefix, bool keep_it)
    : dir(fs::temp_directory_path() / fmt::format("{}_{}", prefix, ::getpid())), keep(keep_it) {
  fs::remove_all(dir);
  fs::create_directories(dir / "images");
  fs::create_directories(dir / "sparse");
  if (keep) spdlog::info("bench reconstruct: COLMAP workspace {}", dir.string());
}

ColmapWorkspace::~ColmapWorkspace() {
  std::error_code ec;
  if (!keep) fs::remove_all(dir, ec);
}

namespace {

// Every model to text; the largest (most registered images) is the one returned.
std::optional<ColmapModel> LargestModel(const ColmapJob& job, const ColmapWorkspace& ws, double* seconds,
                                        std::vector<std::size_t>* sizes) {
  std::optional<ColmapModel> best;
  for (const auto& entry : fs::directory_iterator(ws.dir / "sparse")) {
    if (!entry.is_directory()) continue;
    const fs::path txt = ws.dir / ("txt_" + entry.path().filename().string());
    fs::create_directories(txt);
    *seconds +=
        RunColmap(job.binary, "model_converter",
                  {"--input_path", entry.path().string(), "--output_path", txt.string(), "--output_type", "TXT"},
                  ws.dir / "colmap.log", nullptr);
    ColmapModel model = ReadColmapText(txt);
    sizes->push_back(model.images.size());
    if (!best || model.images.size() > best->images.size()) best = std::move(model);
  }
  std::sort(sizes->rbegin(), sizes->rend());
  return best;
}

// COLMAP's scale is arbitrary: its trajectory is put into metres by the similarity alignment
// first, so its RPE is in metres too; ATE is unchanged by this, its scale error means nothing.
void ScoreColmap(std::vector<tracking::TrajectoryPose> estimate, const std::vector<tracking::TrajectoryPose>& truth,
                 MethodRow* m, Results* out) {
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
  FillErrors(tracking::EvaluateTrajectory(estimate, truth), m);
  m->scale = m->scale_error_percent = m->ate_rigid_m = kNaN;
  AddAlignedPath(m->method, estimate, truth, out);
}

}  // namespace

void RunColmapJob(const ColmapJob& job, const ColmapWorkspace& ws, const capture::Rig& rig,
                  const std::vector<tracking::TrajectoryPose>& truth, Results* out, BenchProgress* overall) {
  MethodRow m;
  m.method = job.method;
  m.machine = MachineNow();
  m.dataset = job.dataset;
  m.frames = job.frames;
  m.images_total = job.images;
  StageProgress progress;
  const fs::path log = ws.dir / "colmap.log";
  const std::string db = (ws.dir / "database.db").string(), images = (ws.dir / "images").string();
  double extract_s = 0;
  long extracted = 0;
  for (const auto& e : job.extractions) {
    extract_s += RunColmap(job.binary, "feature_extractor",
                           {"--database_path", db, "--image_path", images, "--image_list_path", e.list.string(),
                            "--ImageReader.camera_model", e.camera_model, "--ImageReader.single_camera", "1",
                            "--ImageReader.camera_params", e.params, "--SiftExtraction.use_gpu", "0",
                            "--SiftExtraction.num_threads", "-1"},
                           log, [&](const std::string& line) {
                             long done = 0, total = 0;
                             if (ParseBracketCount(line, "Processed file", &done, &total))
                               progress(job.method + " feature_extractor", extracted + done, job.images);
                           });
    extracted += e.images;
  }
  progress.Clear();
  out->stages.push_back({job.method, "feature_extractor", RoundTo(extract_s, 1e2),
                         fmt::format("CPU SIFT, {} images, {}", job.images, job.camera_what)});
  overall->Step(job.method + " features");

  const double match_s =
      RunColmap(job.binary, "sequential_matcher",
                {"--database_path", db, "--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads", "-1",
                 "--SequentialMatching.overlap", std::to_string(job.overlap), "--SequentialMatching.quadratic_overlap",
                 "0", "--SequentialMatching.loop_detection", "0"},
                log, [&](const std::string& line) {
                  long done = 0, total = 0;
                  if (ParseBracketCount(line, "Matching image", &done, &total))
                    progress(job.method + " sequential_matcher", done, total);
                });
  progress.Clear();
  out->stages.push_back({job.method, "sequential_matcher", RoundTo(match_s, 1e2),
                         fmt::format("CPU, overlap {} images ({}), no quadratic overlap, no loop detection",
                                     job.overlap, job.overlap_what)});
  overall->Step(job.method + " matching");

  long registered_now = 0;
  const double map_s =
      RunColmap(job.binary, "mapper",
                {"--database_path", db, "--image_path", images, "--output_path", (ws.dir / "sparse").string(),
                 "--Mapper.num_threads", "-1", "--Mapper.ba_refine_focal_length", "0",
                 "--Mapper.ba_refine_principal_point", "0", "--Mapper.ba_refine_extra_params", "0"},
                log, [&](const std::string& line) {
                  // "Registering image #17 (5)": the count in brackets is the model's registered images.
                  long id = 0, count = 0;
                  const auto at = line.find("Registering image #");
                  if (at != std::string::npos &&
                      std::sscanf(line.c_str() + at, "Registering image #%ld (%ld)", &id, &count) == 2) {
                    registered_now = std::max(registered_now, count);
                    progress(job.method + " mapper (images registered)", registered_now, job.images);
                  }
                });
  progress.Clear();
  overall->Step(job.method + " mapper");

  double convert_s = 0;
  std::vector<std::size_t> sizes;
  const std::optional<ColmapModel> best = LargestModel(job, ws, &convert_s, &sizes);
  out->stages.push_back(
      {job.method, "mapper", RoundTo(map_s, 1e2), fmt::format("CPU, intrinsics fixed, {} model(s)", sizes.size())});
  out->stages.push_back({job.method, "model_converter", RoundTo(convert_s, 1e2), "binary to text"});
  m.seconds = RoundTo(extract_s + match_s + map_s + convert_s, 1e2);
  overall->Step(job.method + " model");
  if (!best || best->images.empty()) {
    m.note = "failed: the mapper made no model";
    out->rows.push_back(m);
    return;
  }
  m.images_registered = static_cast<long>(best->images.size());
  m.points = best->points;
  double units_per_metre = kNaN;
  const std::vector<tracking::TrajectoryPose> estimate = ColmapRigPoses(*best, rig, &units_per_metre);
  m.frames_posed = static_cast<long>(estimate.size());
  std::string models;
  for (std::size_t s : sizes) models += (models.empty() ? "" : ", ") + std::to_string(s);
  m.note = fmt::format("{} model(s) of {} images; rig offsets scaled by {} COLMAP units per metre", sizes.size(),
                       models, Num(units_per_metre, 3));
  try {
    ScoreColmap(estimate, truth, &m, out);
  } catch (const Error& e) {
    m.note += std::string("; not scored: ") + e.what();
  }
  out->rows.push_back(m);
}

void RunOdvrReconstruction(const OdvrRun& run, const std::vector<tracking::TrajectoryPose>& truth, Results* out) {
  MethodRow m;
  m.method = run.method;
  m.machine = MachineNow();
  m.dataset = run.dataset;
  m.frames = run.frames;
  m.images_total = run.frames * run.rig.camera_count();
  tracking::ReconstructionOptions options = run.options;
  options.max_frames = run.frames;
  StageProgress progress;
  tracking::ReconstructionCallbacks callbacks;
  callbacks.progress = [&](const std::string& stage, int done, int total) {
    progress(run.method + " " + stage, done, total > 0 ? total : run.frames);
  };
  const auto t0 = std::chrono::steady_clock::now();
  try {
    auto source = run.open();
    const tracking::Reconstruction r = tracking::Reconstruct(run.rig, *source, options, callbacks);
    m.seconds = RoundTo(SecondsSince(t0), 1e2);
    progress.Clear();
    std::vector<tracking::TrajectoryPose> estimate;
    for (const auto& f : r.frames) {
      if (!f.world_from_rig.AllFinite()) continue;
      estimate.push_back({f.index, f.timestamp, f.world_from_rig.Matrix()});
    }
    m.frames_posed = static_cast<long>(estimate.size());
    m.images_registered = m.frames_posed * run.rig.camera_count();
    m.points = static_cast<long>(r.points.size());
    FillErrors(tracking::EvaluateTrajectory(estimate, truth), &m);
    if (!run.metric) m.scale = m.scale_error_percent = m.ate_rigid_m = m.rpe_m = kNaN;
    AddAlignedPath(run.method, estimate, truth, out);
    double staged = 0;
    for (const auto& s : r.stages) {
      out->stages.push_back({run.method, s.name, RoundTo(s.seconds, 1e2), fmt::format("{} {}", s.inliers, s.what)});
      staged += s.seconds;
    }
    out->stages.push_back(
        {run.method, "other (reading images, setup)", RoundTo(std::max(0.0, m.seconds - staged), 1e2), ""});
    m.note = fmt::format("reprojection RMSE {:.2f} px over {} observations; {} cross-camera links; scale from {}",
                         r.rmse_px, r.observations, r.cross_camera_links,
                         r.scale_source.empty() ? "nothing (up to scale)" : r.scale_source);
    for (const auto& w : r.warnings) m.note += "; warning: " + w;
  } catch (const std::exception& e) {
    // A failure is a result too: the table says so rather than the bench dying without one.
    progress.Clear();
    m.seconds = RoundTo(SecondsSince(t0), 1e2);
    m.note = std::string("failed: ") + e.what();
    spdlog::error("bench reconstruct: {} failed: {}", run.method, e.what());
  }
  for (char& ch : m.note)
    if (ch == '\t' || ch == '\n') ch = ' ';
  out->rows.push_back(m);
}

void WriteTrajectoryPlot(const Results& r, const fs::path& dir, const std::string& stem, const std::string& bench) {
  std::ostringstream gp;
  const std::string paths = stem + "_paths.tsv";
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
     << "set size ratio -1\nset title 'trajectory seen from above (ground-truth world, estimates "
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
  WritePlot(dir, stem, 1000, 900, gp.str(), bench);
}

}  // namespace odvr::app
