#include "engine/lighting/lighting_builder.h"

#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <OpenImageIO/imageio.h>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include <algorithm>
#include <cstdio>
#include "core/error.h"
#include "engine/image/image_io.h"
#include "engine/lighting/lighting_errors.h"
#include "engine/sphere/resample.h"
#include "tests/engine/lighting/lighting_test_maps.h"

namespace odvr::lighting {
namespace {

using odvr::testing::AddDisc;
using odvr::testing::SkyMap;

// Collects what is logged while it lives.
class LogCapture {
 public:
  LogCapture() : sink_(std::make_shared<spdlog::sinks::ostream_sink_mt>(text_)) {
    spdlog::default_logger()->sinks().push_back(sink_);
  }
  ~LogCapture() {
    auto& sinks = spdlog::default_logger()->sinks();
    sinks.erase(std::remove(sinks.begin(), sinks.end(), sink_), sinks.end());
  }
  std::string str() const { return text_.str(); }

 private:
  std::ostringstream text_;
  std::shared_ptr<spdlog::sinks::ostream_sink_mt> sink_;
};

void ExpectFiniteModel(const SgLighting& m) {
  EXPECT_TRUE(std::isfinite(m.constant.x) && std::isfinite(m.constant.y) && std::isfinite(m.constant.z));
  for (const auto& g : m.ToSgs()) {
    ASSERT_TRUE(std::isfinite(g.lambda));
    ASSERT_TRUE(std::isfinite(g.amplitude.x) && std::isfinite(g.amplitude.y) && std::isfinite(g.amplitude.z));
    ASSERT_TRUE(std::isfinite(glm::length(g.axis)));
  }
  for (float v : m.Reconstruct(128, 64).rgb) ASSERT_TRUE(std::isfinite(v));
}

TEST(LightingBuilder, NanInfAndNegativePixelsWarnAndNeverReachTheModel) {
  sphere::EquirectImage frame = SkyMap(512, 256);
  AddDisc(&frame, {0.3, 0.8, -0.5}, 0.03, 2e4f);
  frame.at(3, 3)[0] = std::nanf("");
  frame.at(100, 40)[1] = INFINITY;
  frame.at(200, 60)[2] = -INFINITY;
  frame.at(50, 20)[2] = -3894.f;  // what lossy EXR leaves around a sun
  LogCapture log;
  LightingReport report;
  const SgLighting m = LightingBuilder().Build(frame, &report);
  ExpectFiniteModel(m);
  EXPECT_NE(log.str().find("NaN/Inf"), std::string::npos) << log.str();
  // One bad pixel must not cost the frame its sun.
  EXPECT_EQ(m.peaks.size(), 1u);
}

TEST(LightingBuilder, AllBlackFrameIsAnEmptyModel) {
  LightingReport report;
  const SgLighting m = LightingBuilder().Build(sphere::EquirectImage(256, 128), &report);
  EXPECT_EQ(m.sg_count(), 0);
  EXPECT_TRUE(m.peaks.empty());
  EXPECT_EQ(report.transform.stop_reason, "the frame is black");
  for (float v : m.Reconstruct(64, 32).rgb) EXPECT_EQ(v, 0.f);
}

TEST(LightingBuilder, ConstantFrameIsReproducedToOneThousandthWithFewSgs) {
  // Wider than the peak grid, so the resampling is part of the path too.
  const sphere::EquirectImage frame(2048, 1024, 0.42f);
  LightingReport report;
  const SgLighting m = LightingBuilder().Build(frame, &report);
  EXPECT_TRUE(m.peaks.empty());
  EXPECT_LE(m.sg_count(), 12);
  for (float v : m.Reconstruct(256, 128).rgb) ASSERT_NEAR(v, 0.42f, 0.42e-3f);
}

TEST(LightingBuilder, TinyAndNonEquirectInputsAreClearErrors) {
  LightingBuilder b;
  EXPECT_THROW(b.Build(sphere::EquirectImage(1, 1, 1.f)), Error);
  EXPECT_THROW(b.Build(sphere::EquirectImage(100, 100, 1.f)), Error);
  EXPECT_THROW(b.Build(sphere::EquirectImage(4096, 1024, 1.f)), Error);  // 4:1, after resampling
  try {
    b.Build(sphere::EquirectImage(300, 100, 1.f));
    FAIL() << "a 3:1 frame was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("300x100"), std::string::npos) << e.what();
  }
}

std::string TempPath(const std::string& name) { return ::testing::TempDir() + "lighting_builder_" + name; }

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

TEST(LightingBuilder, LightingJsonRoundTripIsExact) {
  sphere::EquirectImage frame = SkyMap(512, 256);
  AddDisc(&frame, {-0.2, 0.6, 0.7}, 0.04, 3e4f);
  const SgLighting m = LightingBuilder().Build(frame);
  ASSERT_FALSE(m.levels.empty());
  ASSERT_FALSE(m.peaks.empty());
  const std::string path = TempPath("model.json");
  m.Save(path);
  const SgLighting r = SgLighting::Load(path);
  EXPECT_EQ(r.constant, m.constant);
  ASSERT_EQ(r.levels.size(), m.levels.size());
  for (std::size_t i = 0; i < m.levels.size(); ++i) {
    EXPECT_EQ(r.levels[i].level, m.levels[i].level);
    EXPECT_EQ(r.levels[i].lambda, m.levels[i].lambda);
    EXPECT_EQ(r.levels[i].indices, m.levels[i].indices);
    EXPECT_EQ(r.levels[i].amplitudes, m.levels[i].amplitudes);
  }
  ASSERT_EQ(r.peaks.size(), m.peaks.size());
  for (std::size_t i = 0; i < m.peaks.size(); ++i) {
    EXPECT_EQ(r.peaks[i].lambda, m.peaks[i].lambda);
    EXPECT_EQ(r.peaks[i].amplitude, m.peaks[i].amplitude);
    // Load renormalizes the axis; a unit axis survives it to the last bit or two.
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(r.peaks[i].axis[k], m.peaks[i].axis[k], 1e-15);
  }
  // And what a renderer sees is the same.
  EXPECT_EQ(r.Reconstruct(64, 32).rgb, m.Reconstruct(64, 32).rgb);
}

void ExpectOneLineErrorNaming(const std::string& path) {
  try {
    SgLighting::Load(path);
    FAIL() << path << " was accepted";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

TEST(LightingBuilder, TruncatedOrMalformedLightingJsonIsAOneLineError) {
  sphere::EquirectImage frame = SkyMap(256, 128);
  const std::string good = TempPath("good.json");
  LightingBuilder().Build(frame).Save(good);
  std::ifstream in(good);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(text.size(), 100u);

  const std::string truncated = TempPath("truncated.json");
  WriteText(truncated, text.substr(0, text.size() / 2));
  ExpectOneLineErrorNaming(truncated);

  const std::string wrong_format = TempPath("wrong_format.json");
  WriteText(wrong_format, R"({"format": "something-else", "version": 1})");
  ExpectOneLineErrorNaming(wrong_format);

  const std::string missing_key = TempPath("missing_key.json");
  WriteText(missing_key, R"({"format": "odvr-sg-lighting", "version": 1, "constant": [1, 1, 1]})");
  ExpectOneLineErrorNaming(missing_key);

  const std::string bad_index = TempPath("bad_index.json");
  WriteText(bad_index, R"({"format": "odvr-sg-lighting", "version": 1, "constant": [0, 0, 0], "peaks": [],
    "levels": [{"level": 0, "lambda": 5.5, "indices": [12], "amplitudes": [[1, 1, 1]]}]})");
  ExpectOneLineErrorNaming(bad_index);

  ExpectOneLineErrorNaming(TempPath("no_such_file.json"));
}

// Resets the process's resident-memory high-water mark (Linux: "5" to clear_refs), so what is
// measured next is the peak of that step alone, not of everything the process did before.
bool ResetPeakRss() { return static_cast<bool>(std::ofstream("/proc/self/clear_refs") << "5" << std::flush); }

// The high-water mark of resident memory (VmHWM) since the last reset, in MiB.
double PeakRssMib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return -1;
}

double CurrentRssMib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return -1;
}

TEST(LightingBuilder, WideFileIsDownsampledWhileReadWithBoundedMemory) {
  // image_io.h's rule: a file wider than max_width is box-downsampled by a power of two while it
  // is read, a few rows at a time, so peak memory ≈ the output + `factor` rows of input, never
  // the whole frame. An 8192×4096 RGB frame is 384 MiB as float; read to 1024 wide it is 6 MiB.
  const int w = 8192, h = 4096;
  const std::string path = TempPath("wide.exr");
  {
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::HALF);
    spec.attribute("compression", "zip");
    ASSERT_TRUE(out->open(path, spec));
    std::vector<float> row(static_cast<std::size_t>(w) * 3);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        // Column stripes 8 wide and row bands 8 high, so each 8×8 block's mean is known exactly.
        const float v = static_cast<float>((x / 8) % 4) + 0.25f * static_cast<float>((y / 8) % 2);
        row[3 * static_cast<std::size_t>(x)] = v;
        row[3 * static_cast<std::size_t>(x) + 1] = 2 * v;
        row[3 * static_cast<std::size_t>(x) + 2] = (x % 2) ? 1.f : 0.f;  // averages to 0.5
      }
      ASSERT_TRUE(out->write_scanline(y, 0, OIIO::TypeDesc::FLOAT, row.data()));
    }
    ASSERT_TRUE(out->close());
  }
  ASSERT_TRUE(ResetPeakRss()) << "cannot reset the peak RSS to measure the read";
  const double rss_before = CurrentRssMib();
  image::LoadReport report;
  const sphere::EquirectImage img = image::LoadImage(path, {.max_width = 1024, .require_equirect = true}, &report);
  const double rss_growth = PeakRssMib() - rss_before;
  std::printf("8192x4096 EXR read to %dx%d (factor %d): peak RSS grew by %.1f MiB\n", img.width, img.height,
              report.downsample_factor, rss_growth);
  std::filesystem::remove(path);
  EXPECT_EQ(report.file_width, w);
  EXPECT_EQ(report.downsample_factor, 8);
  ASSERT_EQ(img.width, 1024);
  ASSERT_EQ(img.height, 512);
  for (int row = 0; row < img.height; row += 37)
    for (int col = 0; col < img.width; col += 13) {
      const float v = static_cast<float>(col % 4) + 0.25f * static_cast<float>(row % 2);
      ASSERT_NEAR(img.at(col, row)[0], v, 1e-3f) << col << "," << row;
      ASSERT_NEAR(img.at(col, row)[1], 2 * v, 2e-3f) << col << "," << row;
      ASSERT_NEAR(img.at(col, row)[2], 0.5f, 1e-6f) << col << "," << row;
    }
  EXPECT_LT(rss_growth, 96) << "the whole frame (384 MiB as float) was held in memory";

  // A frame too wide for the transform's grid goes through the builder at a bounded size.
  const SgLighting m = LightingBuilder().Build(img);
  ExpectFiniteModel(m);
}

TEST(LightingBuilder, FusedCoarseGridGivesTheSameModelAsResamplingTheResidue) {
  // The detector's coarse grid is DownsampleBox of the residue bit for bit, and the transform
  // derives the same grids from it, so the model must be the same to the last bit; a 1e-6
  // relative tolerance only allows for a compiler contracting a sum differently in the two paths.
  // At 2048 wide the detector also makes the 1024-wide grid in its pass.
  for (int width : {1024, 2048}) {
    SCOPED_TRACE(width);
    sphere::EquirectImage img = SkyMap(width, width / 2);
    AddDisc(&img, {0.5, 0.6, 0.3}, 0.01, 30000.f);
    AddDisc(&img, {-0.4, 0.1, -0.8}, 0.015, 5000.f);
    const auto near = [](float a, float b) { return std::abs(a - b) <= 1e-6f * std::max(1.f, std::abs(b)); };
    for (int levels : {1, 2, 3, 4}) {
      LightingOptions fused_options;
      fused_options.transform.levels = levels;
      fused_options.transform.stop_threshold = 0;
      LightingOptions plain_options = fused_options;
      plain_options.fuse_coarse_grid = false;
      LightingBuilder fused(fused_options), plain(plain_options);
      ASSERT_EQ(fused.FusedFactor(1024, 512), levels == 4 ? 4 : levels == 3 ? 8 : 16);
      EXPECT_EQ(plain.FusedFactor(1024, 512), 1);
      LightingReport fr, pr;
      const SgLighting a = fused.Build(img, &fr), b = plain.Build(img, &pr);
      ASSERT_EQ(fr.peak_detection.peaks.size(), 2u);
      EXPECT_EQ(fr.transform.levels.size(), pr.transform.levels.size());
      EXPECT_EQ(fr.transform.mean_radiance, pr.transform.mean_radiance);
      for (int k = 0; k < 3; ++k) EXPECT_TRUE(near(a.constant[k], b.constant[k])) << levels;
      ASSERT_EQ(a.levels.size(), b.levels.size()) << levels;
      for (std::size_t l = 0; l < a.levels.size(); ++l) {
        ASSERT_EQ(a.levels[l].indices, b.levels[l].indices) << levels;
        for (std::size_t i = 0; i < a.levels[l].amplitudes.size(); ++i)
          for (int k = 0; k < 3; ++k)
            ASSERT_TRUE(near(a.levels[l].amplitudes[i][k], b.levels[l].amplitudes[i][k]))
                << "levels " << levels << " level " << l << " srbf " << i;
      }
      ASSERT_EQ(a.peaks.size(), b.peaks.size());
      for (std::size_t i = 0; i < a.peaks.size(); ++i) EXPECT_EQ(a.peaks[i].amplitude, b.peaks[i].amplitude);
    }
  }
}

TEST(LightingBuilder, WideFrameWithoutPeaksGoesToTheTransformWhole) {
  // The transform box-averages a 2048-wide frame to its 512-wide finest grid itself; through the
  // 1024-wide peak grid first (fuse_coarse_grid off) the grids differ only by rounding.
  sphere::EquirectImage img = SkyMap(2048, 1024);
  AddDisc(&img, {0.5, 0.6, 0.3}, 0.01, 30000.f);
  LightingOptions direct_options;
  direct_options.detect_peaks = false;
  direct_options.transform.stop_threshold = 0;
  LightingOptions resampled_options = direct_options;
  resampled_options.fuse_coarse_grid = false;
  LightingReport dr, rr;
  const SgLighting a = LightingBuilder(direct_options).Build(img, &dr);
  const SgLighting b = LightingBuilder(resampled_options).Build(img, &rr);
  EXPECT_EQ(dr.transform.levels.size(), 5u);
  ASSERT_EQ(a.levels.size(), b.levels.size());
  float largest = 0;
  for (const auto& level : b.levels)
    for (const auto& amplitude : level.amplitudes) largest = std::max({largest, std::abs(amplitude.x)});
  for (std::size_t l = 0; l < a.levels.size(); ++l) {
    ASSERT_EQ(a.levels[l].indices, b.levels[l].indices) << l;
    for (std::size_t i = 0; i < a.levels[l].amplitudes.size(); ++i)
      for (int k = 0; k < 3; ++k)
        ASSERT_NEAR(a.levels[l].amplitudes[i][k], b.levels[l].amplitudes[i][k], 1e-5f * largest)
            << "level " << l << " srbf " << i;
  }
}

TEST(LightingBuilder, ImagesKeptAcrossFramesCarryNothingOver) {
  // The builder, the detector and the transform keep their grids and residues from frame to
  // frame (reshaped, not zeroed): a builder that has seen other frames, of other sizes and with
  // bad pixels, must give each frame the model a fresh one gives it, bit for bit.
  std::vector<sphere::EquirectImage> frames;
  for (int width : {2048, 512, 1024, 2048}) {
    sphere::EquirectImage img = SkyMap(width, width / 2);
    AddDisc(&img, {0.5, 0.6, 0.3 * width / 1024.0}, 0.01, 30000.f);
    frames.push_back(std::move(img));
  }
  frames[2].rgb[7] = std::nanf("");  // through the clamping paths once
  for (bool peaks : {true, false}) {
    SCOPED_TRACE(peaks);
    LightingOptions options;
    options.detect_peaks = peaks;
    options.transform.stop_threshold = 0;
    LightingBuilder reused(options);
    for (std::size_t f = 0; f < frames.size(); ++f) {
      SCOPED_TRACE(f);
      const SgLighting a = reused.Build(frames[f]);
      const SgLighting b = LightingBuilder(options).Build(frames[f]);
      EXPECT_EQ(a.constant, b.constant);
      ASSERT_EQ(a.levels.size(), b.levels.size());
      for (std::size_t l = 0; l < a.levels.size(); ++l) {
        ASSERT_EQ(a.levels[l].indices, b.levels[l].indices);
        ASSERT_EQ(a.levels[l].amplitudes, b.levels[l].amplitudes) << "level " << l;
      }
      ASSERT_EQ(a.peaks.size(), b.peaks.size());
      for (std::size_t i = 0; i < a.peaks.size(); ++i) EXPECT_EQ(a.peaks[i].amplitude, b.peaks[i].amplitude);
    }
  }
}

}  // namespace
}  // namespace odvr::lighting
