// odvr bench decode: how each 360° clip decodes through libav (capture::LibavVideoReader, what
// play, export and reconstruct read with) beside OpenCV's VideoCapture (what odvr read with
// before): the frames each delivers against the container's count, the time per frame, and where
// a seek to the middle frame lands. Writes a Markdown table, the rows (TSV) and a PNG plot.
//
// Where a seek lands is found by content, not by the reader's own word: every frame decoded in
// order is kept as a 64x32 grey thumbnail, and the frame a seek delivers is matched to the
// thumbnail it differs least from (mean absolute difference), so a reader that lands two frames
// early and says it is on the asked one reads as two frames off.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "app/bench/bench_common.h"
#include "app/bench/bench_decode.h"
#include "app/flags/command_flags.h"
#include "capture/libav_video.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/statistics.h"
#include "core/timing.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;

// One reader on one clip.
struct DecodeRun {
  long frames = 0;              // delivered in order, of the first max_frames
  long skipped = 0;             // reported as undecodable (libav) or n/a (OpenCV: -1)
  double ms_per_frame = NAN;    // median over the frames delivered
  long seek_asked = -1;         // the frame a seek asked for
  long seek_landed = -1;        // the frame its content matches
  std::string note;             // why a reader could not run, or stopped
  std::vector<cv::Mat> thumbs;  // the frames in order, 64x32 grey
};

struct DecodeRow {
  std::string clip, codec, size, layout;
  long container_frames = 0;
  bool exact = false;
  DecodeRun libav, opencv;
};

cv::Mat Thumb(const cv::Mat& bgr) {
  cv::Mat grey, small;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::resize(grey, small, cv::Size(64, 32), 0, 0, cv::INTER_AREA);
  return small;
}

// The index of the thumbnail `image` differs least from.
long BestMatch(const std::vector<cv::Mat>& thumbs, const cv::Mat& image) {
  const cv::Mat t = Thumb(image);
  long best = -1;
  double best_diff = 1e30;
  for (std::size_t i = 0; i < thumbs.size(); ++i) {
    const double d = cv::norm(thumbs[i], t, cv::NORM_L1);
    if (d < best_diff) {
      best_diff = d;
      best = static_cast<long>(i);
    }
  }
  return best;
}

DecodeRun RunLibav(const std::string& clip, long max_frames) {
  DecodeRun run;
  try {
    capture::LibavVideoReader reader(clip);
    std::vector<double> ms;
    while (run.frames < max_frames) {
      const auto t0 = SteadyClock::now();
      const auto frame = reader.Next();
      if (!frame) break;
      ms.push_back(MsSince(t0));
      run.thumbs.push_back(Thumb(frame->image));
      ++run.frames;
    }
    run.skipped = reader.skipped_frames();
    if (!reader.read_error().empty()) run.note = reader.read_error();
    run.ms_per_frame = Median(ms);
    if (run.frames >= 3) {
      run.seek_asked = run.frames / 2;
      capture::LibavVideoReader seeker(clip);
      if (seeker.Seek(run.seek_asked))
        if (const auto f = seeker.Next()) run.seek_landed = BestMatch(run.thumbs, f->image);
    }
  } catch (const Error& e) {
    run.note = e.what();
  }
  return run;
}

DecodeRun RunOpenCv(const std::string& clip, long max_frames) {
  DecodeRun run;
  run.skipped = -1;
  cv::VideoCapture capture(clip, cv::CAP_FFMPEG);
  if (!capture.isOpened()) {
    run.note = "VideoCapture cannot open it";
    return run;
  }
  std::vector<double> ms;
  cv::Mat image;
  while (run.frames < max_frames) {
    const auto t0 = SteadyClock::now();
    if (!capture.read(image) || image.empty()) break;
    ms.push_back(MsSince(t0));
    run.thumbs.push_back(Thumb(image));
    ++run.frames;
  }
  run.ms_per_frame = Median(ms);
  if (run.frames >= 3) {
    run.seek_asked = run.frames / 2;
    cv::VideoCapture seeker(clip, cv::CAP_FFMPEG);
    if (seeker.set(cv::CAP_PROP_POS_FRAMES, static_cast<double>(run.seek_asked)) && seeker.read(image) &&
        !image.empty())
      run.seek_landed = BestMatch(run.thumbs, image);
  }
  return run;
}

std::vector<std::string> DefaultClips() {
  // The demo's clips: the rig's 1 s street at 1024×512 and the 10 s drive at 2048×1024.
  std::vector<std::string> clips;
  for (const char* folder : {"demo", "drive"}) {
    const fs::path clip = fs::path(ODVR_SOURCE_DIR) / "media" / folder / "street.mp4";
    if (fs::exists(clip)) clips.push_back(clip.string());
  }
  const fs::path dir = fs::path(ODVR_SOURCE_DIR) / ".." / "shared" / "data" / "video360";
  std::vector<std::string> found;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir)) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (e.is_regular_file() && (ext == ".mp4" || ext == ".mov" || ext == ".mkv" || ext == ".ts" || ext == ".webm"))
        found.push_back(fs::path(e.path()).lexically_normal().string());
    }
  std::sort(found.begin(), found.end());
  clips.insert(clips.end(), found.begin(), found.end());
  return clips;
}

std::string Layout(const capture::VideoProbe& p) {
  std::string stereo = !p.stereo                                        ? "no stereo metadata"
                       : *p.stereo == capture::StereoLayout::kMono      ? "mono"
                       : *p.stereo == capture::StereoLayout::kTopBottom ? "top-bottom"
                                                                        : "side-by-side";
  return (p.projection.empty() ? "no projection metadata" : p.projection) + ", " + stereo;
}

std::string SeekText(const DecodeRun& r) {
  if (r.seek_asked < 0) return "n/a";
  if (r.seek_landed < 0) return "asked " + std::to_string(r.seek_asked) + ": no frame";
  const long off = r.seek_landed - r.seek_asked;
  return "asked " + std::to_string(r.seek_asked) + ": " +
         (off == 0 ? "exact" : (off > 0 ? "+" : "") + std::to_string(off));
}

std::string Ms(double v) {
  if (!std::isfinite(v)) return "n/a";
  std::ostringstream s;
  s.precision(v < 10 ? 2 : 1);
  s << std::fixed << v;
  return s.str();
}

void WriteReport(const BenchDecodeOptions& o, const std::vector<DecodeRow>& rows) {
  fs::create_directories(o.out_dir);
  std::ostringstream tsv;
  tsv << "clip\tcontainer_frames\tlibav_frames\tlibav_ms\tlibav_seek_error\topencv_frames\topencv_ms\topencv_seek_"
         "error\n";
  for (const auto& r : rows) {
    auto err = [](const DecodeRun& x) {
      return x.seek_landed < 0 ? std::string("nan") : std::to_string(x.seek_landed - x.seek_asked);
    };
    tsv << fs::path(r.clip).filename().string() << "\t" << r.container_frames << "\t" << r.libav.frames << "\t"
        << Ms(r.libav.ms_per_frame) << "\t" << err(r.libav) << "\t" << r.opencv.frames << "\t"
        << Ms(r.opencv.ms_per_frame) << "\t" << err(r.opencv) << "\n";
  }
  WriteTextAtomically(fs::path(o.out_dir) / "decode.tsv", tsv.str());

  std::ostringstream md;
  md << "# Decoding 360° clips: libav beside OpenCV's VideoCapture\n\n"
     << "Made by `odvr bench decode` on " << BenchMachineDescription() << ". Each clip read from its start by "
     << "`capture::LibavVideoReader` (what `play`, `export` and `reconstruct` read with) and by OpenCV's "
     << "`cv::VideoCapture` (FFmpeg backend; what odvr read with before), at most " << o.max_frames
     << " frames each. *frames*: delivered in order before the reader stopped, against the container's own count "
     << "(*exact* from an index, else *≈* duration × rate); *skipped*: frames the reader reported undecodable; "
     << "*ms/frame*: the median time of one frame's decode and conversion to 8-bit BGR; *seek*: a fresh reader "
     << "asked for the middle frame of those delivered, and where its first frame lands by content (the "
     << "in-order frame it differs least from, on 64x32 grey thumbnails).\n\n"
     << "| clip | codec | size | metadata | container frames | reader | frames | skipped | ms/frame | seek | note |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    for (const auto* run : {&r.libav, &r.opencv}) {
      const bool lib = run == &r.libav;
      md << "| " << fs::path(r.clip).filename().string() << " | " << r.codec << " | " << r.size << " | " << r.layout
         << " | " << (r.exact ? "" : "≈ ") << r.container_frames << " | " << (lib ? "libav" : "OpenCV") << " | "
         << run->frames << " | " << (run->skipped < 0 ? "n/a" : std::to_string(run->skipped)) << " | "
         << Ms(run->ms_per_frame) << " | " << SeekText(*run) << " | " << run->note << " |\n";
    }
  }
  // What the rows say, reader by reader.
  md << "\n";
  for (const bool lib : {true, false}) {
    long clips_whole = 0, seeks_exact = 0, seeks = 0;
    for (const auto& r : rows) {
      const DecodeRun& run = lib ? r.libav : r.opencv;
      clips_whole += run.frames >= std::min(r.container_frames, o.max_frames);
      seeks += run.seek_asked >= 0;
      seeks_exact += run.seek_asked >= 0 && run.seek_landed == run.seek_asked;
    }
    md << "- **" << (lib ? "libav" : "OpenCV") << "**: every frame (of the first " << o.max_frames << ") of "
       << clips_whole << " of " << rows.size() << " clips; its seek landed on the asked frame on " << seeks_exact
       << " of " << seeks << ".\n";
  }
  std::vector<double> ratios;
  for (const auto& r : rows)
    if (std::isfinite(r.libav.ms_per_frame) && std::isfinite(r.opencv.ms_per_frame) && r.libav.ms_per_frame > 0)
      ratios.push_back(r.opencv.ms_per_frame / r.libav.ms_per_frame);
  if (!ratios.empty())
    md << "- OpenCV's time per frame is " << Ms(Median(ratios)) << "x libav's (median over the clips; "
       << Ms(*std::min_element(ratios.begin(), ratios.end())) << "-"
       << Ms(*std::max_element(ratios.begin(), ratios.end()))
       << "x). Both decode with FFmpeg's own decoders, multithreaded; the time is that of one call as a player makes "
          "it, conversion to BGR included.\n";
  WriteTextAtomically(fs::path(o.out_dir) / "decode.md", md.str());

  std::ostringstream gp;
  gp << "set datafile separator '\\t'\nset datafile columnheaders\nset style data histogram\nset style histogram "
        "cluster gap 1\n"
        "set style fill solid 0.8 border -1\nset ylabel 'ms per frame (median)'\nset xtics rotate by -20\n"
        "set key top left\nset grid ytics\n"
        "plot 'decode.tsv' using 4:xtic(1) title 'libav', '' using 7 title 'OpenCV VideoCapture'\n";
  WritePlot(o.out_dir, "decode", 900, 480, gp.str(), "bench decode");
}

}  // namespace

int RunBenchDecode(const BenchDecodeOptions& options) {
  BenchDecodeOptions o = options;
  if (o.max_frames < 3) throw UsageError("--max-frames", "must be at least 3");
  if (o.clips.empty()) o.clips = DefaultClips();
  if (o.clips.empty())
    throw UsageError("--clips", "none given, and neither the demo nor ../shared/data/video360 is here");
  std::vector<DecodeRow> rows;
  BenchProgress progress("bench decode", static_cast<long>(o.clips.size()));
  for (const auto& clip : o.clips) {
    DecodeRow row;
    row.clip = clip;
    const capture::VideoProbe p = capture::ProbeVideo(clip);  // a file that is no video: the error names it
    row.codec = p.codec;
    row.size = std::to_string(p.width) + "x" + std::to_string(p.height);
    row.layout = Layout(p);
    row.container_frames = p.frame_count;
    row.exact = p.frame_count_exact;
    row.libav = RunLibav(clip, o.max_frames);
    row.opencv = RunOpenCv(clip, o.max_frames);
    rows.push_back(std::move(row));
    progress.Step(fs::path(clip).filename().string());
  }
  WriteReport(o, rows);
  for (const auto& r : rows)
    std::cout << fs::path(r.clip).filename().string() << ": libav " << r.libav.frames << " frames, "
              << Ms(r.libav.ms_per_frame) << " ms/frame, seek " << SeekText(r.libav) << "; OpenCV " << r.opencv.frames
              << " frames, " << Ms(r.opencv.ms_per_frame) << " ms/frame, seek " << SeekText(r.opencv) << "\n";
  std::cout << "bench decode: wrote " << o.out_dir << "/decode.md, decode.tsv, decode.png\n";
  return 0;
}

CommandFn AddBenchDecode(CLI::App* sub) {
  auto o = std::make_shared<BenchDecodeOptions>();
  sub->add_option("--clips", o->clips, "Videos to read (default: the demo and ../shared/data/video360's clips)");
  sub->add_option("--max-frames", o->max_frames, "Frames read from each clip's start at most")->capture_default_str();
  sub->add_option("--out", o->out_dir, "Where the table, TSV and plot go (docs/benchmarks: the committed pages)")
      ->capture_default_str();
  return [o] { return RunBenchDecode(*o); };
}

}  // namespace odvr::app
