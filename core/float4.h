#pragma once
// Four floats in registers (GCC's vector extension), for the per-pixel loops that take
// interleaved RGB four values at a time (the peak detector's scan, the residual transform's
// passes, the box downsampling). Loads and stores go through memcpy, so pointers need no
// alignment; the compiler turns them into plain unaligned moves.
#include <cstring>

namespace odvr::simd {

using V4 = float __attribute__((vector_size(16)));

inline V4 Load4(const float* p) {
  V4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

inline void Store4(float* p, V4 v) { std::memcpy(p, &v, sizeof v); }

}  // namespace odvr::simd
