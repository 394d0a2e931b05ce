#include "app/bench/bench_long_clip.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "app/bench/bench_common.h"
#include "app/bench/bench_sfm.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/timing.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
constexpr double kClipFps = 25;
constexpr long kTenMinutesAt30Fps = 18000;

nlohmann::json Rows(const Eigen::Matrix4d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

// Frame k of the clip is panorama Bounce(k): 0, 1, ..., n-1, n-2, ..., 0, 1, ...
long Bounce(long k, long n) {
  const long period = 2 * (n - 1);
  const long i = k % period;
  return i < n ? i : period - i;
}

LongClipRow ReconstructLongClip(const fs::path& video, const fs::path& truth, long frames, double height_m,
                                const fs::path& work) {
  LongClipRow row;
  row.frames = frames;
  const fs::path out = work / fmt::format("long_{}", frames);
  const fs::path log = work / fmt::format("long_{}.log", frames);
  const std::string self = fs::read_symlink("/proc/self/exe").string();
  const std::string cmd = fmt::format(
      "{} reconstruct --video {} --frames {} --camera-height {} --ground-truth {} --json --out {} > /dev/null 2> {}",
      ShellQuote(self), ShellQuote(video.string()), frames, height_m, ShellQuote(truth.string()),
      ShellQuote(out.string()), ShellQuote(log.string()));
  const auto t0 = SteadyClock::now();
  const int status = std::system(cmd.c_str());
  row.seconds = SecondsSince(t0);
  if (status != 0) {
    std::ifstream in(log);
    std::string line, last;
    while (std::getline(in, line))
      if (!line.empty()) last = line;
    row.note = "failed: " + last;
    return row;
  }
  std::ifstream in(out / "summary.json");
  const nlohmann::json s = nlohmann::json::parse(in);
  row.posed = s.value("frames", 0L);
  row.key_frames = s.value("key_frames", 0L);
  row.peak_memory_mb = s.value("peak_memory_mb", 0.0);
  row.chunks = 1;
  for (const auto& stage : s["stages"])
    if (stage.value("name", "") == "chunks") row.chunks = stage.value("inliers", 1L);
  row.ate_percent = s["evaluation"].value("ate_percent_of_path", 0.0);
  row.scale_error_percent = s["evaluation"].value("scale_error_percent", 0.0);
  return row;
}

}  // namespace

fs::path EncodeH264(const fs::path& frames_dir, long frames, int crf, const fs::path& out) {
  const std::string cmd = "ffmpeg -hide_banner -loglevel error -nostdin -y -framerate 25 -start_number 0 -i " +
                          ShellQuote((frames_dir / "%06d.png").string()) + " -frames:v " + std::to_string(frames) +
                          " -c:v libx264 -preset medium -crf " + std::to_string(crf) + " -pix_fmt yuv420p " +
                          ShellQuote(out.string());
  const int status = std::system(cmd.c_str());
  if (status != 0)
    throw Error("ffmpeg",
                "encoding " + frames_dir.string() + " failed (exit status " + std::to_string(status) + "): " + cmd);
  return out;
}

std::vector<LongClipRow> RunLongClips(const fs::path& dataset, const std::vector<tracking::TrajectoryPose>& truth,
                                      const std::vector<long>& lengths, int crf, double height_m,
                                      const fs::path& work) {
  const long longest = *std::max_element(lengths.begin(), lengths.end());
  std::map<long, Eigen::Matrix4d> pose_of;
  for (const auto& p : truth) pose_of[p.index] = p.world_from_rig;
  const long panoramas = static_cast<long>(pose_of.size());
  if (panoramas < 2 || pose_of.rbegin()->first != panoramas - 1)
    throw Error(dataset.string(), "the long clip needs the truth of frames 0 .. n-1 in a row");
  const fs::path frames_dir = work / "long_frames";
  fs::create_directories(frames_dir);
  nlohmann::json frames = nlohmann::json::array();
  for (long k = 0; k < longest; ++k) {
    const long i = Bounce(k, panoramas);
    fs::create_symlink(fs::absolute(dataset / "pano" / fmt::format("{:06d}.png", i)),
                       frames_dir / fmt::format("{:06d}.png", k));
    frames.push_back(
        {{"index", k}, {"timestamp", static_cast<double>(k) / kClipFps}, {"world_from_rig", Rows(pose_of[i])}});
  }
  const fs::path truth_file = work / "long_truth.json";
  WriteTextAtomically(truth_file, nlohmann::json{{"frames", frames}}.dump());
  const fs::path video = EncodeH264(frames_dir, longest, crf, work / "long.mp4");
  std::vector<LongClipRow> rows;
  for (long n : lengths) rows.push_back(ReconstructLongClip(video, truth_file, n, height_m, work));
  return rows;
}

std::string LongClipSection(const std::vector<LongClipRow>& rows, int crf) {
  std::ostringstream md;
  md << "\n## A long clip: time and memory against its length\n\n"
     << "The dataset's panoramas played forwards and backwards (the camera drives the street to and fro), H.264 crf "
     << crf << ", each length reconstructed by `odvr reconstruct --video … --camera-height` as a user runs it (a "
     << "child process: its peak resident memory is its own, from `summary.json`), against the truth in that "
        "order. Tracks are not linked across passes (nothing closes loops), so each pass adds points as a new "
        "street would.\n\n"
     << "| frames | seconds | s/frame | peak memory (MB) | frames posed | key frames | chunks | ATE (% of path) | "
        "scale error | note |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows)
    md << "| " << r.frames << " | " << Num(r.seconds, 1) << " | " << Num(r.seconds / static_cast<double>(r.frames), 3)
       << " | " << Num(r.peak_memory_mb, 0) << " | " << r.posed << "/" << r.frames << " | " << r.key_frames << " | "
       << r.chunks << " | " << Num(r.ate_percent, 3) << " | " << Num(r.scale_error_percent, 2) << " % | " << r.note
       << " |\n";
  const LongClipRow& last = rows.back();
  if (last.note.empty() && last.frames > 0)
    md << "\nAt the longest row's rate a 10-minute clip at 30 fps (" << kTenMinutesAt30Fps << " frames) takes about "
       << Num(last.seconds / static_cast<double>(last.frames) * kTenMinutesAt30Fps / 60, 0)
       << " minutes on this machine, its memory that of one chunk.\n";
  return md.str();
}

}  // namespace odvr::app
