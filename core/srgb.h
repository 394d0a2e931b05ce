#pragma once
// The sRGB transfer curve (IEC 61966-2-1): 8-bit frames and PNGs are sRGB-encoded, everything in
// memory is linear light (docs/design.md).
#include <array>

namespace odvr {

// Encoded [0, 1] to linear [0, 1], and back (clamped to [0, 1] first).
float SrgbToLinear(float v);
float LinearToSrgb(float v);

// SrgbToLinear(i / 255) for each 8-bit code i: the per-pixel loops look values up.
const std::array<float, 256>& Srgb8ToLinearTable();

}  // namespace odvr
