// Rays against the car's triangles through a BVH (visibility/triangle_bvh.h has the layout; its
// Occluded and ClosestHit are this traversal on the CPU): the Monte-Carlo shader's exact shadow
// rays (RenderOptions::monte_carlo_exact_visibility), the SG shader's peak shadows
// (RenderOptions::exact_peak_shadows) and its specular bounce. The includer sets BVH_BINDING
// (nodes there, triangles at BVH_BINDING + 1) and declares `uniform int uExactTriangles` (0:
// nothing occludes).
layout(std430, binding = BVH_BINDING) readonly buffer BvhNodes { vec4 bvhNodes[]; };          // 2 per node
layout(std430, binding = BVH_BINDING + 1) readonly buffer BvhTriangles { vec4 bvhTriangles[]; };  // 3 per triangle

// visibility::TriangleBvh::Trace: along o + t d, t in (0, t_max), the first triangle found
// (any_hit) or the nearest; its index in the BVH's order, t and the barycentrics (u, v) of
// vertices 1 and 2.
bool bvhTrace(vec3 o, vec3 d, float t_max, bool any_hit, out int hit_triangle, out float hit_t, out vec2 hit_uv) {
  hit_triangle = -1;
  hit_t = t_max;
  hit_uv = vec2(0.0);
  if (uExactTriangles <= 0) return false;
  vec3 inv = 1.0 / d;
  int stack[48];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    int node = stack[--top];
    vec4 lo = bvhNodes[2 * node], hi = bvhNodes[2 * node + 1];
    vec3 a = (lo.xyz - o) * inv, b = (hi.xyz - o) * inv;
    vec3 tn = min(a, b), tf = max(a, b);
    // hit_t shrinks to the nearest hit so far: farther boxes are skipped.
    if (max(max(tn.x, tn.y), max(tn.z, 0.0)) > min(min(min(tf.x, tf.y), tf.z), hit_t)) continue;
    int first = floatBitsToInt(lo.w), count = floatBitsToInt(hi.w);
    if (count == 0) {
      stack[top++] = first;
      stack[top++] = first + 1;
      continue;
    }
    for (int t = first; t < first + count; ++t) {
      vec3 v0 = bvhTriangles[3 * t].xyz, e1 = bvhTriangles[3 * t + 1].xyz - v0, e2 = bvhTriangles[3 * t + 2].xyz - v0;
      vec3 p = cross(d, e2);
      float det = dot(e1, p);
      if (det == 0.0) continue;
      float inv_det = 1.0 / det;
      vec3 s = o - v0;
      float u = dot(s, p) * inv_det;
      if (u < 0.0 || u > 1.0) continue;
      vec3 q = cross(s, e1);
      float v = dot(d, q) * inv_det;
      if (v < 0.0 || u + v > 1.0) continue;
      float th = dot(e2, q) * inv_det;
      if (th > 0.0 && th < hit_t) {
        hit_triangle = t;
        hit_t = th;
        hit_uv = vec2(u, v);
        if (any_hit) return true;
      }
    }
  }
  return hit_triangle >= 0;
}

bool rayOccluded(vec3 o, vec3 d) {
  int triangle;
  float t;
  vec2 uv;
  return bvhTrace(o, d, 3.0e38, true, triangle, t, uv);
}

bool rayClosestHit(vec3 o, vec3 d, float t_max, out int hit_triangle, out float hit_t, out vec2 hit_uv) {
  return bvhTrace(o, d, t_max, false, hit_triangle, hit_t, hit_uv);
}
