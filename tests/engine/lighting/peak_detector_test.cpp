#include "engine/lighting/peak_detector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <map>
#include <numeric>
#include <random>
#include <set>

#include "core/error.h"
#include "core/parallel.h"
#include "engine/image/image_io.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/lighting/lighting_errors.h"
#include "engine/lighting/sg.h"
#include "tests/engine/lighting/lighting_test_maps.h"

namespace odvr::lighting {
namespace {

using odvr::testing::AddDisc;
using odvr::testing::AngleDeg;
using odvr::testing::SkyMap;

// Unit direction at longitude/latitude in degrees, by the convention of engine/sphere/equirect.h.
glm::dvec3 Dir(double lon_deg, double lat_deg) {
  const double lon = lon_deg * kPi / 180, lat = lat_deg * kPi / 180;
  return {std::cos(lat) * std::cos(lon), std::sin(lat), -std::cos(lat) * std::sin(lon)};
}

// Σ (I − sky) dA over the pixels the disc covers: the energy a detector should find.
glm::dvec3 DiscExcess(const sphere::EquirectImage& with, const sphere::EquirectImage& without) {
  glm::dvec3 e(0);
  for (int row = 0; row < with.height; ++row) {
    const double da = sphere::EquirectPixelSolidAngle(row, with.width, with.height);
    for (int col = 0; col < with.width; ++col)
      for (int ch = 0; ch < 3; ++ch) e[ch] += (with.at(col, row)[ch] - without.at(col, row)[ch]) * da;
  }
  return e;
}

// Σ μ ∫G over a peak's SGs: the energy the model puts back.
glm::dvec3 ModelEnergy(const DetectedPeak& p) {
  glm::dvec3 e(0);
  for (const auto& g : p.sgs) e += glm::dvec3(g.amplitude) * Integral(Sg{g.axis, g.lambda, 1});
  return e;
}

// Energy-weighted mean axis of a peak's SGs.
glm::dvec3 PeakAxis(const DetectedPeak& p) {
  glm::dvec3 a(0);
  for (const auto& g : p.sgs) {
    const glm::dvec3 e = glm::dvec3(g.amplitude) * Integral(Sg{g.axis, g.lambda, 1});
    a += (e.x + e.y + e.z) * g.axis;
  }
  return glm::normalize(a);
}

float MaxValue(const sphere::EquirectImage& img) { return *std::max_element(img.rgb.begin(), img.rgb.end()); }

bool AllFinite(const DetectedPeak& p) {
  for (const auto& g : p.sgs)
    if (!std::isfinite(g.lambda) || !std::isfinite(g.amplitude.x) || !std::isfinite(g.amplitude.y) ||
        !std::isfinite(g.amplitude.z) || !std::isfinite(glm::length(g.axis)))
      return false;
  return true;
}

TEST(PeakDetector, SunAHundredThousandTimesTheSkyIsRecoveredAndTakenOut) {
  const sphere::EquirectImage sky = SkyMap(512, 256);
  sphere::EquirectImage frame = sky;
  const glm::dvec3 sun = Dir(37, 41);
  AddDisc(&frame, sun, 1.5 * kPi / 180, 1e5f);
  const PeakDetection d = DetectPeaks(frame);
  EXPECT_FALSE(d.ldr);
  ASSERT_EQ(d.peaks.size(), 1u);
  const DetectedPeak& p = d.peaks[0];
  ASSERT_TRUE(AllFinite(p));
  EXPECT_EQ(p.sgs.size(), 1u) << "a round sun is one SG";
  EXPECT_LT(AngleDeg(p.sgs[0].axis, sun), 1.0);
  const glm::dvec3 truth = DiscExcess(frame, sky);
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(p.energy[ch], truth[ch], 0.03 * truth[ch]) << ch;
    EXPECT_NEAR(ModelEnergy(p)[ch], truth[ch], 0.03 * truth[ch]) << ch;
  }
  // The residue is the sky again: its brightest pixel is the sky's, not a trace of the sun.
  EXPECT_LT(MaxValue(d.residue), 1.01f * MaxValue(sky));
  for (float v : d.residue.rgb) ASSERT_TRUE(std::isfinite(v));

  // Through the builder: the sun stays one peak SG, and nothing in the model is NaN.
  const SgLighting m = LightingBuilder().Build(frame);
  ASSERT_EQ(m.peaks.size(), 1u);
  for (const auto& g : m.ToSgs())
    EXPECT_TRUE(std::isfinite(g.amplitude.x) && std::isfinite(g.amplitude.y) && std::isfinite(g.amplitude.z));
  for (float v : m.Reconstruct(128, 64).rgb) ASSERT_TRUE(std::isfinite(v));
}

// A spot straddling the ±180° seam or covering a pole is one light, not two or a ring of slivers.
void ExpectOneRoundPeakAt(const glm::dvec3& centre, double radius_deg) {
  const sphere::EquirectImage sky = SkyMap(512, 256);
  sphere::EquirectImage frame = sky;
  AddDisc(&frame, centre, radius_deg * kPi / 180, 5e3f);
  const PeakDetection d = DetectPeaks(frame);
  ASSERT_EQ(d.peaks.size(), 1u);
  ASSERT_TRUE(AllFinite(d.peaks[0]));
  EXPECT_EQ(d.peaks[0].sgs.size(), 1u) << "a round spot is one SG";
  EXPECT_LT(AngleDeg(PeakAxis(d.peaks[0]), centre), 1.0);
  const glm::dvec3 truth = DiscExcess(frame, sky);
  EXPECT_NEAR(ModelEnergy(d.peaks[0]).y, truth.y, 0.03 * truth.y);
  EXPECT_LT(MaxValue(d.residue), 1.01f * MaxValue(sky));
}

TEST(PeakDetector, CoarseGridIsTheResiduesBoxAverageBitForBit) {
  // Two suns (one in LDR) and a NaN (the detector sanitizes the frame and scans it again): the
  // coarse grid summed in the scan and refreshed where the peaks took light out must be what
  // DownsampleBox makes of the residue.
  // An LDR frame's clipped suns take the path that keeps the residue.
  for (const bool ldr : {false, true})
    for (int factor : {2, 8, 16}) {
      sphere::EquirectImage img = SkyMap(256, 128);
      if (ldr)
        for (float& v : img.rgb) v *= 0.7f;
      AddDisc(&img, {0.5, 0.6, 0.3}, 0.02, ldr ? 1.f : 4000.f);
      if (!ldr) AddDisc(&img, {0, 0.2, -1}, 0.03, 900.f);  // an LDR frame has one sun
      img.at(7, 90)[1] = std::nanf("");
      const PeakDetection d = DetectPeaksToCoarseGrid(img, factor);
      ASSERT_EQ(d.peaks.size(), ldr ? 1u : 2u) << factor;
      const PeakDetection plain = DetectPeaks(img);
      EXPECT_TRUE(d.residue.empty()) << "an LDR sun is weighed against the coarse grid";
      EXPECT_EQ(d.ldr, ldr);
      const sphere::EquirectImage expected = sphere::DownsampleBox(plain.residue, factor);
      ASSERT_EQ(d.coarse.width, expected.width);
      ASSERT_EQ(d.coarse.height, expected.height);
      for (std::size_t i = 0; i < expected.rgb.size(); ++i)
        ASSERT_EQ(d.coarse.rgb[i], expected.rgb[i]) << "factor " << factor << ", value " << i;
      // And the peaks are those of the detector without the coarse grid.
      ASSERT_EQ(plain.peaks.size(), d.peaks.size());
      // An LDR sun's energy, the prior times the sky's irradiance, is integrated over the coarse
      // grid here and over the residue there: within what the cosine's curvature over a cell of
      // angular size δ changes, second order in δ.
      const double cell = kPi * factor / img.height;
      for (std::size_t i = 0; i < plain.peaks.size(); ++i)
        for (int ch = 0; ch < 3; ++ch)
          if (ldr)
            EXPECT_NEAR(d.peaks[i].energy[ch], plain.peaks[i].energy[ch],
                        0.05 * cell * cell * plain.peaks[i].energy[ch])
                << factor;
          else
            EXPECT_EQ(d.peaks[i].energy[ch], plain.peaks[i].energy[ch]);
      EXPECT_TRUE(plain.coarse.empty());
    }
  EXPECT_THROW(DetectPeaksToCoarseGrid(SkyMap(256, 128), 3), Error);
  EXPECT_THROW(DetectPeaksToCoarseGrid(SkyMap(256, 128), 2, {}, 3), Error);
}

TEST(PeakDetector, ThreadsChangeNothing) {
  // The scan runs in bands of rows on the pool; its sums are added in band order either way.
  // 720 rows: bands of 64 with a short last one; a NaN makes it scan the sanitized frame again.
  ThreadPool pool(3);
  for (const int frame_factor : {1, 2}) {
    sphere::EquirectImage img = SkyMap(1440, 720);
    AddDisc(&img, {0.5, 0.6, 0.3}, 0.02, 4000.f);
    AddDisc(&img, {-0.3, -0.1, 0.9}, 0.04, 700.f);
    img.at(1000, 333)[2] = std::nanf("");
    const PeakDetection serial = DetectPeaksToCoarseGrid(img, 4, {}, frame_factor);
    const PeakDetection threaded = DetectPeaksToCoarseGrid(img, 4, {}, frame_factor, nullptr, &pool);
    ASSERT_EQ(serial.peaks.size(), 2u);
    ASSERT_EQ(threaded.peaks.size(), serial.peaks.size());
    EXPECT_EQ(threaded.threshold, serial.threshold);
    for (std::size_t i = 0; i < serial.peaks.size(); ++i) {
      EXPECT_EQ(threaded.peaks[i].energy, serial.peaks[i].energy);
      EXPECT_EQ(threaded.peaks[i].sgs.front().amplitude, serial.peaks[i].sgs.front().amplitude);
    }
    ASSERT_EQ(threaded.coarse.rgb.size(), serial.coarse.rgb.size());
    EXPECT_TRUE(threaded.coarse.rgb == serial.coarse.rgb) << "frame factor " << frame_factor;
  }
}

TEST(PeakDetector, FrameBoxAveragedInTheScanIsTheDetectorOnTheDownsampledFrame) {
  sphere::EquirectImage img = SkyMap(512, 256);
  AddDisc(&img, {0.5, 0.6, 0.3}, 0.02, 4000.f);
  img.at(9, 200)[0] = -3.f;
  const PeakDetection d = DetectPeaksToCoarseGrid(img, 4, {}, 2);
  const PeakDetection plain = DetectPeaks(sphere::DownsampleBox(img, 2));
  ASSERT_EQ(d.peaks.size(), 1u);
  ASSERT_EQ(plain.peaks.size(), 1u);
  EXPECT_EQ(d.peaks[0].energy, plain.peaks[0].energy);
  EXPECT_EQ(d.peaks[0].sgs.front().amplitude, plain.peaks[0].sgs.front().amplitude);
  EXPECT_EQ(d.threshold, plain.threshold);
  const sphere::EquirectImage expected = sphere::DownsampleBox(plain.residue, 4);
  ASSERT_EQ(d.coarse.rgb.size(), expected.rgb.size());
  for (std::size_t i = 0; i < expected.rgb.size(); ++i) ASSERT_EQ(d.coarse.rgb[i], expected.rgb[i]) << i;
}

TEST(PeakDetector, SpotStraddlingTheSeamIsOnePeak) {
  SCOPED_TRACE("seam");
  ExpectOneRoundPeakAt(Dir(180, 20), 3);
}

TEST(PeakDetector, SpotAtEachPoleIsOnePeak) {
  {
    SCOPED_TRACE("zenith");
    ExpectOneRoundPeakAt(Dir(0, 90), 3);
  }
  {
    SCOPED_TRACE("nadir");
    ExpectOneRoundPeakAt(Dir(0, -90), 3);
  }
  {
    // Off-centre over the pole: in the image it is a band across every column, far wider than
    // high, yet on the sphere it is round.
    SCOPED_TRACE("near the zenith");
    ExpectOneRoundPeakAt(Dir(60, 87), 4);
  }
}

TEST(PeakDetector, ElongatedSourceIsSplitIntoTwoOrThreeSgs) {
  const sphere::EquirectImage sky = SkyMap(512, 256);
  sphere::EquirectImage frame = sky;
  // A strip light: a row of touching discs along the equator, 10° long, 2° wide (compact enough
  // as a whole for min_lambda: one SG of λ ~800).
  for (double lon = -4; lon <= 4; lon += 0.5) AddDisc(&frame, Dir(lon, 10), 1 * kPi / 180, 2e3f);
  const PeakDetection d = DetectPeaks(frame);
  ASSERT_EQ(d.peaks.size(), 1u);
  const DetectedPeak& p = d.peaks[0];
  ASSERT_TRUE(AllFinite(p));
  EXPECT_GE(p.sgs.size(), 2u);
  EXPECT_LE(p.sgs.size(), 3u);
  // The SGs spread along the strip, not on top of each other, and all lie on it.
  double spread = 0;
  for (const auto& g : p.sgs) {
    const glm::dvec2 lonlat(std::atan2(-g.axis.z, g.axis.x) * 180 / kPi, std::asin(g.axis.y) * 180 / kPi);
    EXPECT_NEAR(lonlat.y, 10, 1.5);
    EXPECT_LT(std::abs(lonlat.x), 5);
    for (const auto& h : p.sgs) spread = std::max(spread, AngleDeg(g.axis, h.axis));
  }
  EXPECT_GT(spread, 3);
  EXPECT_LT(AngleDeg(PeakAxis(p), Dir(0, 10)), 1.0);
  const glm::dvec3 truth = DiscExcess(frame, sky);
  EXPECT_NEAR(ModelEnergy(p).y, truth.y, 0.03 * truth.y);
}

// The components the detector finds through its candidate blocks, against a plain labelling of
// the whole frame: every bright pixel joined with each bright 8-neighbour (columns wrapping at
// the seam) and every bright pixel of row 0, and of row h−1, joined with the others of its row.
std::set<std::vector<int>> WholeFrameComponents(const sphere::EquirectImage& f, double threshold, bool ldr) {
  const int w = f.width, h = f.height;
  const auto bright = [&](int col, int row) {
    const float* p = f.at(col, row);
    return ldr ? std::min({p[0], p[1], p[2]}) >= threshold : 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2] > threshold;
  };
  std::vector<int> parent(static_cast<std::size_t>(w) * h);
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x) x = parent[static_cast<std::size_t>(x)];
    return x;
  };
  const auto join = [&](int a, int b) { parent[static_cast<std::size_t>(find(a))] = find(b); };
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      if (!bright(col, row)) continue;
      for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
          const int r2 = row + dr, c2 = (col + dc + w) % w;
          if (r2 >= 0 && r2 < h && bright(c2, r2)) join(row * w + col, r2 * w + c2);
        }
      if (row == 0 || row == h - 1)
        for (int c2 = 0; c2 < w; ++c2)
          if (bright(c2, row)) join(row * w + col, row * w + c2);
    }
  std::map<int, std::vector<int>> groups;
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col)
      if (bright(col, row)) groups[find(row * w + col)].push_back(row * w + col);
  std::set<std::vector<int>> out;
  for (auto& [root, pixels] : groups) out.insert(pixels);
  return out;
}

// The candidate blocks only skip work: for any block size, including sizes that do not divide
// the frame and blocks of one pixel, the components are exactly those of the whole frame, on
// scattered specks, a spot over the seam, spots near both poles and runs of the first and last
// rows joined only through their pole, and a polar cap of thousands of pixels, in HDR and LDR.
TEST(PeakDetector, CandidateBlocksFindExactlyTheWholeFramesComponents) {
  sphere::EquirectImage frame(250, 125, 0.2f);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> col(0, 249), row(0, 124);
  std::uniform_real_distribution<float> level(0.5f, 3.f);
  for (int i = 0; i < 600; ++i) {
    float* p = frame.at(col(rng), row(rng));
    p[0] = p[1] = p[2] = level(rng);
  }
  AddDisc(&frame, Dir(180, 0), 3 * kPi / 180, 2.f);
  AddDisc(&frame, Dir(0, 84), 4 * kPi / 180, 2.f);
  AddDisc(&frame, Dir(90, -84), 4 * kPi / 180, 2.f);
  // Runs of row 0 and of row 124 apart from each other: one component each, through its pole.
  for (const int c : {10, 11, 130, 200})
    for (const int r : {0, 124}) std::fill_n(frame.at(c, r), 3, 2.f);
  // The same specks under a bright cap of 22° radius over the north pole and the seam: one
  // component of thousands of pixels, sorted by the counting passes (small ones by std::sort),
  // whose pole row is joined once however many of its pixels the fill reaches.
  sphere::EquirectImage capped = frame;
  AddDisc(&capped, Dir(180, 70), 22 * kPi / 180, 2.f);
  for (const auto* f : {&frame, &capped})
    for (const bool ldr : {false, true}) {
      const double threshold = ldr ? 0.98 : 1.0;
      const auto truth = WholeFrameComponents(*f, threshold, ldr);
      ASSERT_GT(truth.size(), 100u);
      std::size_t largest = 0;
      for (const auto& c : truth) largest = std::max(largest, c.size());
      if (f == &capped) {
        EXPECT_GT(largest, 3000u);
      }
      for (const int block : {1, 7, 32, 1000}) {
        const auto found = BrightComponents(*f, threshold, ldr, block);
        const std::set<std::vector<int>> got(found.begin(), found.end());
        EXPECT_EQ(found.size(), got.size()) << "a component found twice, block " << block;
        EXPECT_TRUE(got == truth) << "block " << block << (ldr ? " LDR" : " HDR") << ": " << got.size() << " vs "
                                  << truth.size() << " components";
      }
    }
}

// An LDR sky of linear values in (0, 1) with a sun clipped at 1.
sphere::EquirectImage LdrSky(const glm::dvec3& sun) {
  sphere::EquirectImage frame = SkyMap(512, 256);
  for (float& v : frame.rgb) v *= 0.6f;
  AddDisc(&frame, sun, 2 * kPi / 180, 1.f);
  return frame;
}

// Cosine-weighted integral of `image` over the hemisphere around `axis`: the irradiance a
// surface facing `axis` receives from it.
glm::dvec3 Irradiance(const sphere::EquirectImage& image, const glm::dvec3& axis) {
  glm::dvec3 e(0);
  for (int row = 0; row < image.height; ++row) {
    const double da = sphere::EquirectPixelSolidAngle(row, image.width, image.height);
    for (int col = 0; col < image.width; ++col) {
      const double c = glm::dot(sphere::EquirectPixelDirection(col, row, image.width, image.height), axis);
      if (c > 0)
        for (int ch = 0; ch < 3; ++ch) e[ch] += c * da * image.at(col, row)[ch];
    }
  }
  return e;
}

// The failure park.exr and sunrise.exr showed (bilinearly enlarged, as the bench does): a
// component bright in luminance whose one-pixel ring is brighter than its pixels in one channel.
// Residue and peaks must still add up to the frame's energy in every channel; filling the
// component with the ring's level put blue light at the sun that was never there.
TEST(PeakDetector, ResidueAndPeaksKeepTheFramesEnergyWhenTheRingOutshinesAChannel) {
  sphere::EquirectImage frame(256, 128);
  for (float& v : frame.rgb) v = 0.1f;
  const glm::dvec3 centre = Dir(40, 10);
  const double radius = 5 * kPi / 128;  // five pixels
  // Lit from a ring of blue (luminance 5.2, under the threshold of ~9) around a yellow core
  // (luminance 93) whose blue is far below the ring's.
  for (int row = 0; row < frame.height; ++row)
    for (int col = 0; col < frame.width; ++col) {
      const double a = std::acos(
          std::clamp(glm::dot(sphere::EquirectPixelDirection(col, row, frame.width, frame.height), centre), -1.0, 1.0));
      float* p = frame.at(col, row);
      if (a < radius) {
        p[0] = p[1] = 100, p[2] = 2;
      } else if (a < radius + 2.5 * kPi / 128) {
        p[0] = p[1] = 1, p[2] = 60;
      }
    }
  // The core (7° across, one SG of λ ~270) is broader than min_lambda admits; the subject here
  // is the residue's fill, so the λ gate is off.
  PeakDetectorOptions o;
  o.min_lambda = 0;
  const PeakDetection d = DetectPeaks(frame, o);
  ASSERT_EQ(d.peaks.size(), 1u);
  ASSERT_TRUE(AllFinite(d.peaks[0]));
  const glm::dvec3 model = DiscExcess(d.residue, sphere::EquirectImage(256, 128)) + ModelEnergy(d.peaks[0]);
  const glm::dvec3 truth = DiscExcess(frame, sphere::EquirectImage(256, 128));
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(model[ch], truth[ch], 1e-3 * truth[ch]) << "channel " << ch;
  // The core's blue is 2 against the ring's 60: the peak holds next to no blue.
  EXPECT_LT(ModelEnergy(d.peaks[0]).z, 0.01 * ModelEnergy(d.peaks[0]).x);
}

// dawn.exr's glow: a region over the threshold but only a few times its surroundings is left to
// the hierarchy; the same region ten times brighter than them is a light.
TEST(PeakDetector, GlowOnlyAFewTimesItsSurroundingsIsNoPeak) {
  for (const float core : {20.f, 60.f}) {
    sphere::EquirectImage frame(256, 128, 0.1f);
    const glm::dvec3 centre = Dir(-30, 20);
    AddDisc(&frame, centre, 15 * kPi / 180, 3.f);
    AddDisc(&frame, centre, 5 * kPi / 180, core);
    const PeakDetection d = DetectPeaks(frame);
    EXPECT_LT(d.threshold, core) << "the core is over the threshold";
    EXPECT_GT(d.threshold, 3.0) << "the surroundings are not";
    EXPECT_EQ(d.peaks.size(), core < 10 * 3.f ? 0u : 1u) << "core " << core << " over surroundings 3";
  }
}

// bridge.exr's failure: a broad glow far brighter than its surroundings (contrast over
// min_contrast, area under max_area_fraction) fitted as one SG of λ ~ 200 is no light; the
// hierarchy keeps it. A sun of half a degree beside it still becomes a peak.
TEST(PeakDetector, BroadBrightBlobStaysInTheHierarchyWhileASunIsStillAPeak) {
  sphere::EquirectImage frame(512, 256, 0.1f);
  const glm::dvec3 blob = Dir(-60, 10), sun = Dir(70, 30);
  AddDisc(&frame, blob, 8 * kPi / 180, 60.f);  // contrast 600, 0.06 sr
  AddDisc(&frame, sun, 0.6 * kPi / 180, 2e4f);
  const PeakDetection d = DetectPeaks(frame);
  ASSERT_EQ(d.peaks.size(), 1u);
  EXPECT_LT(AngleDeg(PeakAxis(d.peaks[0]), sun), 0.5);
  EXPECT_GT(d.peaks[0].sgs.front().lambda, 1e4);
  // The blob is untouched in the residue: its light stays for the transform.
  const glm::dvec2 px = sphere::EquirectPixel(blob, 512, 256);
  EXPECT_EQ(d.residue.at(static_cast<int>(px.x), static_cast<int>(px.y))[1], 60.f);
  // Without the gate, the blob is a peak of λ ~ 4/r² (r = 8°: ~205), under the default gate.
  PeakDetectorOptions ungated;
  ungated.min_lambda = 0;
  const PeakDetection u = DetectPeaks(frame, ungated);
  ASSERT_EQ(u.peaks.size(), 2u);
  const DetectedPeak& broad = AngleDeg(PeakAxis(u.peaks[0]), blob) < 2 ? u.peaks[0] : u.peaks[1];
  EXPECT_LT(AngleDeg(PeakAxis(broad), blob), 2.0);
  for (const auto& g : broad.sgs) EXPECT_LT(g.lambda, PeakDetectorOptions{}.min_lambda);
}

TEST(PeakDetector, ClippedLdrSunStillYieldsAPeakFromTheSkyPrior) {
  const glm::dvec3 sun = Dir(-70, 35);
  const sphere::EquirectImage frame = LdrSky(sun);
  ASSERT_LE(MaxValue(frame), 1.f);
  const PeakDetection d = DetectPeaks(frame);
  EXPECT_TRUE(d.ldr);
  ASSERT_EQ(d.peaks.size(), 1u);
  const DetectedPeak& p = d.peaks[0];
  ASSERT_TRUE(AllFinite(p));
  EXPECT_TRUE(p.estimated_from_clipped_ldr);
  EXPECT_LT(AngleDeg(PeakAxis(p), sun), 1.0);
  // The rule of peak_detector.h: the sun's energy (its irradiance on a surface facing it) is
  // ldr_sun_to_sky_ratio × what the rest of the sky gives that surface. The clipped pixels held
  // far less (1.0 each), so the estimate is much larger than what they show.
  const PeakDetectorOptions defaults;
  const glm::dvec3 sky_irradiance = Irradiance(d.residue, PeakAxis(p));
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(ModelEnergy(p)[ch], defaults.ldr_sun_to_sky_ratio * sky_irradiance[ch], 0.01 * ModelEnergy(p)[ch]);
    EXPECT_NEAR(p.energy[ch], ModelEnergy(p)[ch], 1e-3 * p.energy[ch]);
  }
  const double clipped_energy = 2 * kPi * (1 - std::cos(2 * kPi / 180));
  EXPECT_GT(p.energy.y, 100 * clipped_energy);

  // The rule is linear in the prior.
  PeakDetectorOptions twice;
  twice.ldr_sun_to_sky_ratio = 2 * defaults.ldr_sun_to_sky_ratio;
  const PeakDetection d2 = DetectPeaks(frame, twice);
  ASSERT_EQ(d2.peaks.size(), 1u);
  EXPECT_NEAR(d2.peaks[0].energy.y, 2 * p.energy.y, 1e-3 * p.energy.y);
}

// Clipped is not bright in an LDR frame: a room's white grid lines, a blown-out floor, a clipped
// disc below the horizon are no sun (each became one of estimated amplitude ~2000, an error of
// 200 % in the diffuse light); the same disc above the horizon still is.
TEST(PeakDetector, ClippedLdrPixelsAreASunOnlyWhereASunCanBe) {
  const auto room = [] {
    sphere::EquirectImage frame = SkyMap(512, 256);
    for (float& v : frame.rgb) v = 0.25f + 0.4f * v / 3.0f;  // a grey room, nothing clipped
    // White strips on the walls, 1.4° wide and 6° long, apart from each other.
    for (int k = 0; k < 8; ++k)
      for (int y = 60; y < 69; ++y)
        for (int x = 32 + 64 * k; x < 34 + 64 * k; ++x)
          for (int c = 0; c < 3; ++c) frame.at(x, y)[c] = 1.0f;
    return frame;
  };
  sphere::EquirectImage lines = room();
  EXPECT_EQ(DetectPeaks(lines).peaks.size(), 0u) << "white strips";
  sphere::EquirectImage below = room();
  AddDisc(&below, Dir(40, -30), 3 * kPi / 180, 1.f);
  EXPECT_EQ(DetectPeaks(below).peaks.size(), 0u) << "a clipped disc below the horizon";
  sphere::EquirectImage blown = room();
  AddDisc(&blown, Dir(40, 40), 35 * kPi / 180, 1.f);
  EXPECT_EQ(DetectPeaks(blown).peaks.size(), 0u) << "a blown-out area 70° across";
  sphere::EquirectImage sun = room();
  AddDisc(&sun, Dir(40, 30), 3 * kPi / 180, 1.f);
  const PeakDetection d = DetectPeaks(sun);
  ASSERT_EQ(d.peaks.size(), 1u);
  EXPECT_TRUE(d.peaks[0].estimated_from_clipped_ldr);
  EXPECT_LT(AngleDeg(PeakAxis(d.peaks[0]), Dir(40, 30)), 1.0);
}

// A street at 1024 wide as an LDR video holds it: the sun clipped in one pixel with the sky glowing
// round it, and clipped specks lower down — a lamp post's highlight, a sign's edge — in dark
// surrounds, each of larger solid angle than the sun's pixel nearer the zenith. By energy (all read
// 1) the specks crowded the sun out of the ranking and each became a "sun" of the prior's energy;
// an LDR frame has one sun, the candidate that glows.
TEST(PeakDetector, AnLdrFrameHasOneSunTheOneWhoseSkyGlows) {
  const int w = 1024, h = 512;
  const glm::dvec3 sun = Dir(-14, 42);
  sphere::EquirectImage frame(w, h);
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      const glm::dvec3 d = sphere::EquirectPixelDirection(col, row, w, h);
      const double glow = 0.5 * std::exp(-(1 - glm::dot(d, sun)) * 300);  // circumsolar, ~5° wide
      float* p = frame.at(col, row);
      const double sky = d.y > 0 ? 0.25 + 0.2 * d.y : 0.05;  // the ground, dark
      p[0] = static_cast<float>(std::min(0.95, 0.8 * sky + glow));
      p[1] = static_cast<float>(std::min(0.95, 0.9 * sky + glow));
      p[2] = static_cast<float>(std::min(0.95, 1.1 * sky + glow));
    }
  const auto clip = [&](const glm::dvec3& d) {
    const double lat = std::asin(d.y), lon = std::atan2(-d.z, d.x);
    const int col = static_cast<int>((1 - lon / kPi) * w / 2), row = static_cast<int>((kPi / 2 - lat) / kPi * h);
    float* p = frame.at(col, row);
    p[0] = p[1] = p[2] = 1.0f;
  };
  // Specks in dark surrounds: facades from 5° to 20° up, all round the street.
  for (int k = 0; k < 24; ++k) {
    const glm::dvec3 d = Dir(15.0 * k + 3, 5 + (k % 4) * 5);
    for (int row = 0; row < h; ++row)  // a dark facade patch round each speck
      for (int col = 0; col < w; ++col)
        if (glm::dot(sphere::EquirectPixelDirection(col, row, w, h), d) > std::cos(6 * kPi / 180))
          for (int c = 0; c < 3; ++c) frame.at(col, row)[c] = 0.04f;
    clip(d);
  }
  clip(sun);
  const PeakDetection d = DetectPeaks(frame);
  ASSERT_TRUE(d.ldr);
  ASSERT_EQ(d.peaks.size(), 1u) << "one sun, not a speck each";
  EXPECT_GE(d.ldr_glow.x, PeakDetectorOptions{}.ldr_min_glow_margin * d.ldr_glow.y) << "the sun's sky glows";
  EXPECT_TRUE(d.peaks[0].estimated_from_clipped_ldr);
  EXPECT_LT(AngleDeg(PeakAxis(d.peaks[0]), sun), 0.5);
  // With more suns allowed the specks come in too (a lamp's highlight is no sun): the gate is
  // the number, and the glow ranks the sun first.
  PeakDetectorOptions many;
  many.ldr_max_suns = 8;
  const PeakDetection all = DetectPeaks(frame, many);
  ASSERT_EQ(all.peaks.size(), 8u);
  EXPECT_LT(AngleDeg(PeakAxis(all.peaks[0]), sun), 0.5);
  // Two clipped pixels that glow alike, as a white room's grid-line crossings do: neither is the
  // sun, whichever of them the ranking would put first.
  sphere::EquirectImage twins = frame;
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      const glm::dvec3 dir = sphere::EquirectPixelDirection(col, row, w, h);
      const double twin_glow = 0.5 * std::exp(-(1 - glm::dot(dir, Dir(120, 42))) * 300);
      for (int c = 0; c < 3; ++c)
        twins.at(col, row)[c] = std::min(0.95f, twins.at(col, row)[c] + static_cast<float>(twin_glow));
    }
  clip(sun);
  const auto clip_twin = [&](const glm::dvec3& dir) {
    const double lat = std::asin(dir.y), lon = std::atan2(-dir.z, dir.x);
    float* p = twins.at(static_cast<int>((1 - lon / kPi) * w / 2), static_cast<int>((kPi / 2 - lat) / kPi * h));
    p[0] = p[1] = p[2] = 1.0f;
  };
  clip_twin(sun);
  clip_twin(Dir(120, 42));
  const PeakDetection alike = DetectPeaks(twins);
  EXPECT_EQ(alike.peaks.size(), 0u) << "two suns alike: neither";
  EXPECT_LT(alike.ldr_glow.x, PeakDetectorOptions{}.ldr_min_glow_margin * alike.ldr_glow.y);
  EXPECT_GT(alike.ldr_glow.y, 0.0);
}

TEST(PeakDetector, LdrFrameWithoutClippingHasNoPeak) {
  sphere::EquirectImage frame = SkyMap(256, 128);
  for (float& v : frame.rgb) v *= 0.6f;
  const PeakDetection d = DetectPeaks(frame);
  EXPECT_TRUE(d.ldr);
  EXPECT_TRUE(d.peaks.empty());
  EXPECT_EQ(d.residue.rgb, frame.rgb);
}

TEST(PeakDetector, BadOptionsAndTinyFramesAreClearErrors) {
  PeakDetectorOptions o;
  o.threshold_factor = 1;
  EXPECT_THROW(DetectPeaks(SkyMap(64, 32), o), Error);
  o = {};
  o.max_sgs_per_peak = 4;
  EXPECT_THROW(DetectPeaks(SkyMap(64, 32), o), Error);
  o = {};
  o.ldr_max_suns = -1;
  EXPECT_THROW(DetectPeaks(SkyMap(64, 32), o), Error);
  o = {};
  o.ldr_glow_radius_deg = 0;
  EXPECT_THROW(DetectPeaks(SkyMap(64, 32), o), Error);
  o = {};
  o.ldr_min_glow_margin = 0.9;
  EXPECT_THROW(DetectPeaks(SkyMap(64, 32), o), Error);
  EXPECT_THROW(DetectPeaks(sphere::EquirectImage(1, 1, 1.f)), Error);
}

sphere::EquirectImage LoadEnv(const std::string& name) {
  return image::LoadImage(std::string(ODVR_SHARED_DIR) + "/data/env/" + name + ".exr");
}

bool HaveEnv(const std::string& name) {
  return std::filesystem::exists(std::string(ODVR_SHARED_DIR) + "/data/env/" + name + ".exr");
}

TEST(PeakDetector, RealSkyMapHasOnePeakAtTheSun) {
  if (!HaveEnv("sky")) GTEST_SKIP() << "../shared/data/env/sky.exr is absent (the shared test data)";
  const sphere::EquirectImage frame = LoadEnv("sky");
  // The sun: the brightest pixel by luminance.
  int best_col = 0, best_row = 0;
  double best = -1;
  for (int row = 0; row < frame.height; ++row)
    for (int col = 0; col < frame.width; ++col) {
      const float* p = frame.at(col, row);
      const double l = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
      if (l > best) best = l, best_col = col, best_row = row;
    }
  const glm::dvec3 sun = sphere::EquirectPixelDirection(best_col, best_row, frame.width, frame.height);
  const PeakDetection d = DetectPeaks(frame);
  EXPECT_FALSE(d.ldr);
  ASSERT_GE(d.peaks.size(), 1u);
  ASSERT_TRUE(AllFinite(d.peaks[0]));
  // The brightest peak is the sun, within a pixel or two of its brightest pixel (0.7° each).
  EXPECT_LT(AngleDeg(PeakAxis(d.peaks[0]), sun), 1.5);
  // It holds most of the map's energy above the sky level around it.
  EXPECT_LT(MaxValue(d.residue), 0.05f * static_cast<float>(best));
}

// The claim: taking the peaks out first makes the model better where it matters.
// `glossy200`: whether the sharpest error is claimed too (see the sunrise test).
void ExpectPeaksHelp(const std::string& name, bool glossy200 = true) {
  if (!HaveEnv(name)) GTEST_SKIP() << "../shared/data/env/" << name << ".exr is absent (the shared test data)";
  const sphere::EquirectImage frame = LoadEnv(name);
  LightingOptions with, without;
  without.detect_peaks = false;
  const SgLighting a = LightingBuilder(with).Build(frame);
  const SgLighting b = LightingBuilder(without).Build(frame);
  EXPECT_GE(a.peaks.size(), 1u);
  const LightingErrorEvaluator ev(frame);
  const LightingErrors ea = ev.Evaluate(a), eb = ev.Evaluate(b);
  std::printf("%s with peaks: diffuse %.4f glossy20 %.4f glossy200 %.4f rel_l2 %.4f (%d SGs)\n", name.c_str(),
              ea.diffuse, ea.glossy20, ea.glossy200, ea.rel_l2, a.sg_count());
  std::printf("%s without   : diffuse %.4f glossy20 %.4f glossy200 %.4f rel_l2 %.4f (%d SGs)\n", name.c_str(),
              eb.diffuse, eb.glossy20, eb.glossy200, eb.rel_l2, b.sg_count());
  EXPECT_LT(ea.diffuse, eb.diffuse);
  EXPECT_LT(ea.glossy20, eb.glossy20);
  if (glossy200) {
    EXPECT_LT(ea.glossy200, eb.glossy200);
  }
}

TEST(PeakDetector, PeaksLowerTheConvolvedErrorsOnSky) { ExpectPeaksHelp("sky"); }
TEST(PeakDetector, PeaksLowerTheConvolvedErrorsOnPark) { ExpectPeaksHelp("park"); }
// Without peaks, the coarse correction (ResidualTransformOptions::coarse_correction) took
// sunrise's glossy-200 error from 0.0268 to 0.0173 (1024 wide), below the 0.0244 with peaks, where
// the sun's free-form SG's shape error dominates; peaks still halve the diffuse error and cut the
// glossy-20 one (512 wide: 0.0016 / 0.0068 against 0.0032 / 0.0111).
TEST(PeakDetector, PeaksLowerTheBroadConvolvedErrorsOnSunrise) { ExpectPeaksHelp("sunrise", false); }

}  // namespace
}  // namespace odvr::lighting
