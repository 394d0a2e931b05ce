#pragma once
// Peak detection (seed §4.4.4, DESIGN.md §4): the few pixels that hold a sun's or a lamp's
// energy become free-form SGs (own axis, λ and RGB amplitude) and are taken out of the frame
// before the residual transform, so they are neither counted twice nor smeared over the
// hierarchy, and each gets its own visibility cone for a sharp shadow.
//
// HDR frames: pixels brighter than `threshold_factor` × the mean radiance are grouped into
// connected components (8-connected, joined across the ±180° seam and at each pole), looking
// only into the `candidate_block`-sized blocks whose brightest pixel is over the threshold.
// A component whose brightest pixel is under `min_contrast` × its surrounding level is a glow, left
// to the hierarchy. The 10 is chosen, not derived: it sits in the wide gap between the suns'
// contrast and the brightest glow's over ../shared/data/env, and a glow taken as a peak raises the
// glossy errors many times over.
// A component whose single fitted SG has λ under `min_lambda` is also left to the hierarchy: it is
// broad (a window, a large lamp, a glow), levels 0–3 (λ up to 364.5) resolve it, and free SGs
// fitted to its shape do worse. With the gate no map's errors are worse than without peaks except
// two whose compact lights fit well above the gate; the suns fit far above it. So an elongated
// light is split into 2–3 SGs only when it is compact as a whole: a strip up to ~12° long.
//
// LDR frames (every value ≤ 1): a sun is a compact blob clipped at 255, its true intensity lost.
// Clipped is not bright, though: a white wall, a grid line, a window are clipped too, and as
// "suns" of estimated energy they put bright phantom lights on a room's white lines.
// A clipped component counts only where a sun can be: above the horizon, compact (within
// `ldr_max_sun_radius_deg` of its centre), round (principal axes within `ldr_max_elongation`)
// and standing out from its ring (the ring under `ldr_max_ring_level` × the clip level, not the
// clipped core of a larger blown-out area). Its energy is then estimated from a sky-to-sun prior: the sun's irradiance
// on a surface facing it is `ldr_sun_to_sky_ratio` (default 4, a clear day's direct-to-diffuse ratio at mid elevations)
// times the irradiance the rest of the sky gives that surface. One sun at most (`ldr_max_suns`):
// the candidate whose surround glows most (`ldr_glow_radius_deg`), as the sky does round the sun
// and not round a clipped highlight on a post; clipped values alone cannot rank them. A sun is one
// of a kind: unless the first glows `ldr_min_glow_margin` times more than the next (a white room's
// grid-line crossings glow alike), no candidate is taken.
#include <glm/vec2.hpp>
#include <vector>

#include "engine/lighting/sg_lighting.h"
#include "engine/sphere/equirect_image.h"

namespace odvr {
class ThreadPool;
}

namespace odvr::lighting {

struct PeakDetectorOptions {
  double threshold_factor = 20;     // HDR: brighter than this × mean radiance
  double max_area_fraction = 0.01;  // a "peak" larger than this share of the sphere is not one
  int max_peaks = 8;                // the brightest components, by energy
  double min_contrast = 10;         // HDR: brightest pixel over the surrounding level, else a glow
  double min_lambda = 400;          // a component whose one fitted SG is broader is left to the hierarchy
  int max_sgs_per_peak = 3;
  double elongation_for_split = 2.0;  // principal-axis ratio above which a component is split
  double ldr_clip_level = 0.98;       // linear value treated as clipped in an LDR frame
  double ldr_sun_to_sky_ratio = 4.0;
  double ldr_min_elevation_deg = 0;    // a sun is above the horizon
  double ldr_max_sun_radius_deg = 25;  // the sun's disc with its bloom and flare, clipped
  double ldr_max_elongation = 2.0;     // principal-axis ratio: a disc's is 1, a line's many
  double ldr_max_ring_level = 0.9;     // the ring's luminance at most this × the clip level
  // An LDR frame has one sun: a clipped facade, sign or its reflection given the sky prior's
  // energy would double the light. Among the candidates the one that glows most is taken.
  int ldr_max_suns = 1;
  double ldr_glow_radius_deg = 5;  // the surround whose mean luminance ranks LDR candidates
  // ... and it must glow this many times more than the next candidate, or no sun is taken.
  double ldr_min_glow_margin = 1.5;
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
  // LDR: the glow of the two most glowing clipped candidates of a sun's shape (0: none), whose
  // ratio decided whether the first is the sun (PeakDetectorOptions::ldr_min_glow_margin).
  glm::dvec2 ldr_glow{0};
  double ms = 0;
  // From DetectPeaksToCoarseGrid only: the residue box-averaged, bit for bit
  // sphere::DownsampleBox(residue, coarse_factor), summed in the detector's one pass over the
  // frame and recomputed only in the cells the peaks changed, so the transform starts from its
  // finest working grid without another pass over (or a copy of) the full-resolution residue.
  sphere::EquirectImage coarse;
};

PeakDetection DetectPeaks(const sphere::EquirectImage& frame, const PeakDetectorOptions& options = {});
// The same, taking the frame's storage for the residue (the caller's copy is spared: 6 MB at
// 1024×512).
PeakDetection DetectPeaks(sphere::EquirectImage&& frame, const PeakDetectorOptions& options = {});
// The same peaks, with PeakDetection::coarse filled (`coarse_factor` ≥ 2 must divide the frame's
// sides) instead of the residue (left empty, except for an LDR frame): the frame is read once
// and never copied, unless it holds NaN/Inf/negative pixels. With `frame_factor` > 1 the peaks
// are found on the frame box-averaged by it (DownsampleBox bit for bit), made row by row in the
// same pass, into `grid_storage` when given (scratch a caller keeps across frames), and
// `coarse_factor` applies to that grid.
// The pass over the frame runs in bands of rows on `pool` when given (the same result).
// `coarse_storage`, when given, is moved into PeakDetection::coarse to be filled (storage a caller
// hands back after each frame, so the grid's pages are neither faulted in nor zeroed every frame).
PeakDetection DetectPeaksToCoarseGrid(const sphere::EquirectImage& frame, int coarse_factor,
                                      const PeakDetectorOptions& options = {}, int frame_factor = 1,
                                      sphere::EquirectImage* grid_storage = nullptr, ThreadPool* pool = nullptr,
                                      sphere::EquirectImage* coarse_storage = nullptr);

// The detector's connected components of bright pixels (HDR: luminance > threshold; LDR: every
// channel >= threshold), each as ascending pixel indices row·width + col, found through the
// candidate blocks as DetectPeaks finds them. For tests against a whole-frame labelling.
std::vector<std::vector<int>> BrightComponents(const sphere::EquirectImage& frame, double threshold, bool ldr,
                                               int candidate_block = PeakDetectorOptions{}.candidate_block);

}  // namespace odvr::lighting
