#pragma once
// Structural similarity (Wang, Bovik, Sheikh & Simoncelli 2004) of two single-channel images,
// averaged over a mask: the usual 11×11 Gaussian window (σ = 1.5), C1 = (0.01 L)², C2 = (0.03 L)²
// with L the dynamic range the caller states (HDR images: normalise them first).
#include <vector>

namespace odvr::image {

// `a`, `b`: width × height values, top row first. `mask` (same size, or empty for every pixel):
// pixels whose mask > 0.5 are averaged. Window taps outside the image are left out (the window
// is renormalised). Throws odvr::Error for mismatched sizes, a non-positive range or an empty mask.
double MeanSsim(const std::vector<float>& a, const std::vector<float>& b, int width, int height,
                const std::vector<float>& mask, double dynamic_range = 1.0);

}  // namespace odvr::image
