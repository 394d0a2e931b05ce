#pragma once
// Peak detection (seed §4.4.4, DESIGN.md §4): the few pixels that hold a sun's or a lamp's
// energy become free-form SGs (own axis, λ and RGB amplitude) and are taken out of the frame
// before the residual transform, so they are neither counted twice nor smeared over the
// hierarchy, and each gets its own visibility cone for a sharp shadow.
//
// HDR frames: pixels brighter than `threshold_factor` × the mean radiance are grouped into
// connected components (8-connected, joined across the ±180° seam and at each pole), looking
// only into the `candidate_block`-sized blocks whose brightest pixel is over the threshold.
// A component whose brightest pixel is under `min_contrast` × its surrounding level is a glow,
// left to the hierarchy. The 10 is chosen, not derived: it sits in the gap measured over
// ../shared/data/env (suns 128–3300×, dawn's glow 4.2×, which as peaks raised glossy200 6×).
// Per component, the excess over the surrounding level b (the mean of a one-pixel ring) is the
// peak: energy E = Σ (I − b) dA, axis = the energy-weighted mean direction, and λ from the
// spread: for an SG, E[1 − cos θ] ≈ 1/λ, and a pixel of angular size Δ adds Δ²/12, so
// λ = 1 / (E[1 − cos θ] + Δ²/12); μ = E / ∫G. Elongated components (a lamp, a glint) get 2–3
// SGs by k-means on their pixels' directions. The component's pixels keep min(I, b) per channel in
// the residue, so residue + peaks hold exactly the frame's energy.
//
// LDR frames (every value ≤ 1): a sun is a compact blob clipped at 255, its true intensity lost.
// Its energy is then estimated from a sky-to-sun prior: the sun's irradiance on a surface facing
// it is `ldr_sun_to_sky_ratio` (default 4, a clear day's direct-to-diffuse ratio at mid
// elevations) times the irradiance the rest of the sky gives that surface.
#include <vector>

#include "engine/lighting/sg_lighting.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::lighting {

struct PeakDetectorOptions {
  double threshold_factor = 20;     // HDR: brighter than this × mean radiance
  double max_area_fraction = 0.01;  // a "peak" larger than this share of the sphere is not one
  int max_peaks = 8;                // the brightest components, by energy
  double min_contrast = 10;         // HDR: brightest pixel over the surrounding level, else a glow
  int max_sgs_per_peak = 3;
  double elongation_for_split = 2.0;  // principal-axis ratio above which a component is split
  double ldr_clip_level = 0.98;       // linear value treated as clipped in an LDR frame
  double ldr_sun_to_sky_ratio = 4.0;
  // Side of the blocks whose brightest pixel the first pass records; only blocks with a bright
  // pixel are labelled. Any size gives the same components.
  int candidate_block = 32;
  void Check() const;
};

struct DetectedPeak {
  std::vector<RgbSg> sgs;  // 1–3
  int pixels = 0;
  glm::dvec3 energy{0};  // Σ (I − b) dA per channel
  bool estimated_from_clipped_ldr = false;
};

struct PeakDetection {
  std::vector<DetectedPeak> peaks;
  sphere::EquirectImage residue;  // the frame with the peaks taken out
  double threshold = 0;
  bool ldr = false;
  double ms = 0;
};

PeakDetection DetectPeaks(const sphere::EquirectImage& frame, const PeakDetectorOptions& options = {});
// The same, taking the frame's storage for the residue (the caller's copy is spared: 6 MB at
// 1024×512).
PeakDetection DetectPeaks(sphere::EquirectImage&& frame, const PeakDetectorOptions& options = {});

// The detector's connected components of bright pixels (HDR: luminance > threshold; LDR: every
// channel >= threshold), each as ascending pixel indices row·width + col, found through the
// candidate blocks as DetectPeaks finds them. For tests against a whole-frame labelling.
std::vector<std::vector<int>> BrightComponents(const sphere::EquirectImage& frame, double threshold, bool ldr,
                                               int candidate_block = PeakDetectorOptions{}.candidate_block);

}  // namespace odvr::lighting
