#version 450
// RenderOptions::read_layers off: the render's counts (RenderCounts) summed on the GPU, so that a
// player reads back a few numbers per work group instead of 16 bytes per shaded sample and the
// car's coverage (triple_product_renderer.cpp sums the same on the CPU when the layers come back).
// Each invocation sums a stride of samples in registers, each work group its invocations' sums by
// a tree in shared memory, and writes them to its own slot; the CPU adds up the groups' slots.
// No atomics: the atomic version crashed an NVIDIA driver (a SIGSEGV on its first use, before any
// frame was shown) where llvmpipe ran it. 64-bit sums are (low, high) pairs of uints.
layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer Counts { uvec4 counts[]; };  // lobes, cones, triples, SGs
layout(std430, binding = 1) readonly buffer PixelFlags { uint pixelFlags[]; };
// Per work group kTotals uints from gl_WorkGroupID.x * kTotals: [0] car samples, [1] ground
// samples, [2] fully sampled pixels, then (low, high) pairs: lobes, cones, SGs and triples over
// car samples, cones and triples over every sample.
layout(std430, binding = 2) writeonly buffer GroupTotals { uint groupTotals[]; };
layout(rgba32f, binding = 0) readonly uniform image2D uSampleCar;  // alpha: the car's coverage per sample
uniform ivec2 uSamplesSize;
uniform int uPixels;    // output pixels (adaptive supersampling: pixelFlags' length)
uniform int uHasFlags;  // adaptive supersampling: count pixelFlags == 1

const int kGroup = 256;
const int kCounters = 3;
const int kPairs = 6;
const int kTotals = kCounters + 2 * kPairs;
shared uint sTotals[kTotals * kGroup];  // row t, column: the invocation

void main() {
  int local = int(gl_LocalInvocationIndex);
  int samples = uSamplesSize.x * uSamplesSize.y;
  int stride = int(gl_NumWorkGroups.x) * kGroup;
  uint car = 0u, ground = 0u, fully = 0u;
  uint low[kPairs], high[kPairs];
  for (int i = 0; i < kPairs; ++i) {
    low[i] = 0u;
    high[i] = 0u;
  }
  for (int index = int(gl_GlobalInvocationID.x); index < max(samples, uPixels); index += stride) {
    if (index < samples) {
      uvec4 c = counts[index];
      bool onCar = imageLoad(uSampleCar, ivec2(index % uSamplesSize.x, index / uSamplesSize.x)).a > 0.0;
      uint value[kPairs] = uint[kPairs](onCar ? c.x : 0u, onCar ? c.y : 0u, onCar ? c.w : 0u, onCar ? c.z : 0u, c.y, c.z);
      for (int i = 0; i < kPairs; ++i) {
        uint sum = low[i] + value[i];
        high[i] += sum < value[i] ? 1u : 0u;
        low[i] = sum;
      }
      if (onCar) {
        ++car;
      } else if (c.x > 0u) {
        ++ground;
      }
    }
    if (uHasFlags != 0 && index < uPixels && pixelFlags[index] == 1u) ++fully;
  }
  sTotals[0 * kGroup + local] = car;
  sTotals[1 * kGroup + local] = ground;
  sTotals[2 * kGroup + local] = fully;
  for (int i = 0; i < kPairs; ++i) {
    sTotals[(kCounters + 2 * i) * kGroup + local] = low[i];
    sTotals[(kCounters + 2 * i + 1) * kGroup + local] = high[i];
  }
  for (int step = kGroup / 2; step > 0; step /= 2) {
    memoryBarrierShared();
    barrier();
    if (local < step) {
      for (int t = 0; t < kCounters; ++t) sTotals[t * kGroup + local] += sTotals[t * kGroup + local + step];
      for (int i = 0; i < kPairs; ++i) {
        int l = (kCounters + 2 * i) * kGroup + local, h = l + kGroup;
        uint a = sTotals[l], sum = a + sTotals[l + step];
        sTotals[h] += sTotals[h + step] + (sum < a ? 1u : 0u);
        sTotals[l] = sum;
      }
    }
  }
  memoryBarrierShared();
  barrier();
  if (local < kTotals) groupTotals[int(gl_WorkGroupID.x) * kTotals + local] = sTotals[local * kGroup];
}
