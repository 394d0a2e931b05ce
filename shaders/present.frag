#version 450
// FramePresenter's GPU path: a renderer's linear composite (rows top first) times the exposure,
// encoded as 8-bit sRGB into the window's back buffer, whose rows grow upward. The CPU path
// (FramePresenter::Show of an image) encodes through a 4096-entry table: the two agree within one
// step of 255 (tests/app/player/frame_presenter_test.cpp).
layout(binding = 0) uniform sampler2D uLinear;
uniform float uExposure;
uniform vec2 uTargetSize;  // the viewport, pixels
out vec4 fragColor;

float srgb(float x) {  // image::LinearToSrgb
  x = clamp(x, 0.0, 1.0);
  return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

void main() {
  vec2 uv = vec2(gl_FragCoord.x / uTargetSize.x, 1.0 - gl_FragCoord.y / uTargetSize.y);
  vec3 c = texture(uLinear, uv).rgb * uExposure;
  fragColor = vec4(srgb(c.r), srgb(c.g), srgb(c.b), 1.0);
}
