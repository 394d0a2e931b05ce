#version 450
// The residual transform's stop and rejection rules on the GPU, after each level (one
// invocation), so that the CPU can queue every level without reading a sum back in between: the
// gate closes when the level says the transform stops (the residue entering it already below the
// threshold, the level not reducing the RMS residue or keeping no SRBF, or the residue it leaves
// below the threshold), and the gated passes of the later levels then return at once. The CPU
// replays the same rules on the same sums afterwards and keeps the levels they accept: the
// comparisons here are the ones it makes, in double (residual_transform_gpu.cpp).
layout(local_size_x = 1) in;

layout(std430, binding = 0) readonly buffer Totals { double totals[]; };
layout(std430, binding = 1) readonly buffer Flags { uint flags[]; };  // per level: SRBFs kept
layout(std430, binding = 9) buffer Gate {
  uint gate_closed;
  uint levels_run;  // levels that reached this pass with the gate open
};

uniform int uLevel;
uniform int uBeforeSlot;
uniform int uAfterSlot;
uniform double uAbsLimit;  // stop threshold × mean radiance as a Σ (|r|+|g|+|b|) dA

void main() {
  if (gate_closed != 0u) return;
  levels_run += 1u;
  double before_abs = totals[8 * uBeforeSlot + 3], before_sq = totals[8 * uBeforeSlot + 4];
  double after_abs = totals[8 * uAfterSlot + 3], after_sq = totals[8 * uAfterSlot + 4];
  bool converged = uLevel > 0 && before_abs < uAbsLimit;
  bool rejected = !(after_sq < before_sq && flags[uLevel] > 0u);
  if (converged || rejected || after_abs < uAbsLimit) gate_closed = 1u;
}
