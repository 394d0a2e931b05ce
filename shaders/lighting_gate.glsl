// The residual transform's level gate, read first by every pass of a level: lighting_gate.comp
// closes it once the transform has stopped, so that the levels queued after the stop do nothing.
layout(std430, binding = 9) readonly buffer Gate { uint gate_closed; };
