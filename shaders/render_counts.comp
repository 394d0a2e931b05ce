#version 450
// RenderOptions::read_layers off: the render's counts (RenderCounts) summed on the GPU, so that a
// player reads back 15 numbers instead of 16 bytes per shaded sample and the car's coverage
// (triple_product_renderer.cpp sums the same on the CPU when the layers come back). Each
// invocation sums a stride of samples, each work group its invocations' sums in shared memory;
// 64-bit totals are kept as (low, high) pairs of uints.
layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer Counts { uvec4 counts[]; };  // lobes, cones, triples, SGs
layout(std430, binding = 1) readonly buffer PixelFlags { uint pixelFlags[]; };
// [0] car samples, [1] ground samples, [2] fully sampled pixels, then (low, high) pairs:
// lobes, cones, SGs and triples over car samples, cones and triples over every sample.
layout(std430, binding = 2) buffer Totals { uint totals[]; };
layout(rgba32f, binding = 0) readonly uniform image2D uSampleCar;  // alpha: the car's coverage per sample
uniform ivec2 uSamplesSize;
uniform int uPixels;    // output pixels (adaptive supersampling: pixelFlags' length)
uniform int uHasFlags;  // adaptive supersampling: count pixelFlags == 1

const int kPairs = 6;
shared uint sCar, sGround, sFully;
shared uint sLow[kPairs], sHigh[kPairs];

// 64-bit sums as (low, high): the carry is where the low word wrapped.
uvec2 add64(uvec2 sum, uint value) {
  uint low = sum.x + value;
  return uvec2(low, sum.y + (low < value ? 1u : 0u));
}

void addShared64(int slot, uvec2 value) {
  uint before = atomicAdd(sLow[slot], value.x);
  atomicAdd(sHigh[slot], value.y + (before > 0xFFFFFFFFu - value.x ? 1u : 0u));
}

void main() {
  uint local = gl_LocalInvocationIndex;
  if (local == 0u) {
    sCar = 0u;
    sGround = 0u;
    sFully = 0u;
    for (int i = 0; i < kPairs; ++i) {
      sLow[i] = 0u;
      sHigh[i] = 0u;
    }
  }
  barrier();
  // Each invocation sums a stride of samples in registers first: one shared atomic per invocation
  // and quantity, not per sample (on a CPU rasterizer the atomics were most of the pass).
  int samples = uSamplesSize.x * uSamplesSize.y;
  int stride = int(gl_NumWorkGroups.x * gl_WorkGroupSize.x);
  uint car = 0u, ground = 0u, fully = 0u;
  uvec2 sums[kPairs];
  for (int i = 0; i < kPairs; ++i) sums[i] = uvec2(0u);
  for (int index = int(gl_GlobalInvocationID.x); index < max(samples, uPixels); index += stride) {
    if (index < samples) {
      uvec4 c = counts[index];
      sums[4] = add64(sums[4], c.y);
      sums[5] = add64(sums[5], c.z);
      float alpha = imageLoad(uSampleCar, ivec2(index % uSamplesSize.x, index / uSamplesSize.x)).a;
      if (alpha > 0.0) {
        ++car;
        sums[0] = add64(sums[0], c.x);
        sums[1] = add64(sums[1], c.y);
        sums[2] = add64(sums[2], c.w);
        sums[3] = add64(sums[3], c.z);
      } else if (c.x > 0u) {
        ++ground;
      }
    }
    if (uHasFlags != 0 && index < uPixels && pixelFlags[index] == 1u) ++fully;
  }
  atomicAdd(sCar, car);
  atomicAdd(sGround, ground);
  atomicAdd(sFully, fully);
  for (int i = 0; i < kPairs; ++i)
    if (sums[i] != uvec2(0u)) addShared64(i, sums[i]);
  barrier();
  if (local == 0u) {
    atomicAdd(totals[0], sCar);
    atomicAdd(totals[1], sGround);
    atomicAdd(totals[2], sFully);
    for (int i = 0; i < kPairs; ++i) {
      uint before = atomicAdd(totals[3 + 2 * i], sLow[i]);
      uint carry = before > 0xFFFFFFFFu - sLow[i] ? 1u : 0u;
      atomicAdd(totals[4 + 2 * i], sHigh[i] + carry);
    }
  }
}
