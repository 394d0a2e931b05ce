#version 450
// G-buffer pass of the triple-product renderer: world-space vertices through an OpenCV pinhole
// camera. Clip y grows downward with the image row, so framebuffer row 0 is the image's top row
// (the renderer reads every layer top row first without flipping).
layout(location = 0) in vec3 aPosition;  // world, metres
layout(location = 1) in vec3 aNormal;    // world, unit
layout(location = 2) in vec2 aUv0;
layout(location = 3) in vec2 aUv1;
layout(location = 4) in vec4 aTangent;  // xyz world, w handedness; zero when absent

uniform mat4 uClipFromWorld;

out vec3 vPosition;
out vec3 vNormal;
out vec2 vUv0;
out vec2 vUv1;
out vec4 vTangent;

void main() {
  vPosition = aPosition;
  vNormal = aNormal;
  vUv0 = aUv0;
  vUv1 = aUv1;
  vTangent = aTangent;
  gl_Position = uClipFromWorld * vec4(aPosition, 1.0);
}
