// The renderer against a Cycles render we did not write: street_a's relight_ref of frame 10 (the
// car on a 60 m shadow catcher, lit only by pano_hdr/000010.exr as a distant environment,
// 128 spp; ../shared/data/street_a/README.md). Same car pose, camera and environment here:
// - Blender's world is Z-up; ours is Y-up through C: (x, y, z) → (x, z, −y).
// - The panorama is in the rig frame (x forward, y left, z up), and odvr's equirect convention
//   is that frame's Y-up form: an odvr direction d is C d_rig, so the lighting's directions go
//   to the world by C R_world_from_rig Cᵀ.
// - Camera: world_from_persp_cam_opencv, rotated by C; fy = 457.007 px on 640×360 is a
//   42.996° vertical fov with the principal point at the centre, as ours.
// Rendered at half size (320×180) against the reference box-filtered 2×2, to keep the test short.
// Measured errors are printed; the bounds sit a little above them (see the report).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <vector>

#include "engine/image/image_io.h"
#include "engine/lighting/lighting_builder.h"
#include "engine/lighting/sg.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/scene/gltf_scene.h"
#include "tests/engine/gl/gl_test_context.h"

namespace odvr::render {
namespace {

using CyclesReferenceGL = odvr::testing::GlTest;

const std::filesystem::path kStreet = std::filesystem::path(ODVR_SHARED_DIR) / "data/street_a";

glm::dmat4 Matrix4(const nlohmann::json& rows) {
  glm::dmat4 m(1.0);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[c][r] = rows.at(static_cast<std::size_t>(r)).at(static_cast<std::size_t>(c));
  return m;
}

const glm::dmat3 kYupFromZup(glm::dvec3(1, 0, 0), glm::dvec3(0, 0, -1), glm::dvec3(0, 1, 0));  // columns

double Luma(const float* c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

struct Scene {
  glm::dmat4 world_from_car;
  PinholeCamera camera;
  glm::dmat3 world_from_lighting;
};

Scene StreetFrame10(int width, int height) {
  std::ifstream f(kStreet / "car_pose.json");
  const auto j = nlohmann::json::parse(f);
  const auto& fr = j.at("frames").at(0);
  EXPECT_EQ(fr.at("frame").get<int>(), 10);
  Scene s;
  s.world_from_car = Matrix4(fr.at("world_yup_from_car_gltf"));
  const glm::dmat4 cam = Matrix4(fr.at("world_from_persp_cam_opencv"));
  s.camera.position = kYupFromZup * glm::dvec3(cam[3]);
  s.camera.world_from_camera = kYupFromZup * glm::dmat3(cam);
  s.camera.vfov_deg = j.at("persp_camera").at("vfov_deg").get<double>();
  s.camera.width = width;
  s.camera.height = height;
  const glm::dmat3 rig = glm::dmat3(Matrix4(fr.at("world_from_rig")));
  s.world_from_lighting = kYupFromZup * rig * glm::transpose(kYupFromZup);
  return s;
}

// `values` (channels per pixel) of a w×h image box-filtered by `factor`.
std::vector<float> BoxFilter(const std::vector<float>& values, int w, int h, int channels, int factor) {
  const int ow = w / factor, oh = h / factor;
  std::vector<float> out(static_cast<std::size_t>(ow) * oh * channels, 0.f);
  for (int y = 0; y < oh * factor; ++y)
    for (int x = 0; x < ow * factor; ++x)
      for (int c = 0; c < channels; ++c)
        out[(static_cast<std::size_t>(y / factor) * ow + x / factor) * channels + c] +=
            values[(static_cast<std::size_t>(y) * w + x) * channels + c] / static_cast<float>(factor * factor);
  return out;
}

TEST_F(CyclesReferenceGL, StreetFrame10CarAndShadow) {
  const auto ref_path = kStreet / "augment/frame_000010/relight_ref.exr";
  if (!std::filesystem::exists(ref_path)) GTEST_SKIP() << ref_path << " is absent (the shared test data)";
  constexpr int kFactor = 2;
  const sphere::EquirectImage ref_full = image::LoadImage(ref_path);
  int aw = 0, ah = 0;
  const std::vector<float> alpha_full = image::LoadAlpha(ref_path, &aw, &ah);
  ASSERT_EQ(aw, ref_full.width);
  const int w = ref_full.width / kFactor, h = ref_full.height / kFactor;
  const std::vector<float> ref = BoxFilter(ref_full.rgb, aw, ah, 3, kFactor);
  const std::vector<float> ref_alpha = BoxFilter(alpha_full, aw, ah, 1, kFactor);

  const Scene s = StreetFrame10(w, h);
  const sphere::EquirectImage env =
      image::LoadImage(kStreet / "pano_hdr/000010.exr", {.max_width = 8192, .require_equirect = true});
  lighting::LightingBuilder builder;
  const lighting::SgLighting model = builder.Build(env);
  RenderOptions o;
  o.voxel_resolution = 128;
  TripleProductRenderer renderer(scene::LoadGltfScene(kStreet / "car.glb"), s.world_from_car, o);
  renderer.SetLighting(model, s.world_from_lighting);
  renderer.SetEnvironment(env);
  const RenderResult r = renderer.Render(s.camera);
  if (std::getenv("ODVR_RENDER_DIAG")) {
    for (const auto& p : model.peaks) {
      const glm::dvec3 d = s.world_from_lighting * p.axis;
      const double e = lighting::Integral({p.axis, p.lambda, 1.0});
      std::printf("peak world dir %.3f %.3f %.3f lambda %.0f energy %.3f %.3f %.3f\n", d.x, d.y, d.z, p.lambda,
                  e * p.amplitude.x, e * p.amplitude.y, e * p.amplitude.z);
    }
    std::printf("constant %.3f levels %zu\n", model.constant.y, model.levels.size());
    for (int variant = 0; variant < 4; ++variant) {
      RenderOptions o2 = o;
      o2.trace.max_distance = 1e-4;
      if (variant >= 1) o2.lobes.warp = material::WarpMode::kAnisotropicSplit;
      if (variant >= 2) o2.lobes.cosine = material::CosineTerm::kAsSg;
      if (variant == 3) o2.lobes.warp = material::WarpMode::kIsotropic;
      TripleProductRenderer r2(scene::LoadGltfScene(kStreet / "car.glb"), s.world_from_car, o2);
      r2.SetLighting(model, s.world_from_lighting);
      const RenderResult u = r2.Render(s.camera, variant ? ShadeDevice::kCpu : ShadeDevice::kGpu);
      std::printf("variant %d (split %d, cosine SG %d)\n", variant, variant == 1 || variant == 2, variant >= 2);
      double a = 0, b = 0;
      for (std::size_t i = 0; i < ref_alpha.size(); ++i)
        if (ref_alpha[i] > 0.99f && u.car_alpha[i] > 0.5f) {
          a += Luma(&u.car.rgb[3 * i]);
          b += Luma(&ref[3 * i]);
        }
      std::printf("unshadowed car / Cycles %.4f\n", a / b);
      // By row band and by Cycles brightness.
      for (int band = 0; band < 6; ++band) {
        double sa = 0, sb = 0, sc = 0;
        int n = 0;
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * w + x;
            if (!(ref_alpha[i] > 0.99f && u.car_alpha[i] > 0.5f)) continue;
            if ((y - 60) * 6 / 80 != band) continue;
            sa += Luma(&u.car.rgb[3 * i]);
            sc += Luma(&r.car.rgb[3 * i]);
            sb += Luma(&ref[3 * i]);
            ++n;
          }
        std::printf("rows %d..%d: %d px, Cycles mean %.4f, unshadowed/Cycles %.3f shadowed/Cycles %.3f\n",
                    60 + band * 80 / 6, 60 + (band + 1) * 80 / 6, n, sb / std::max(n, 1), sa / sb, sc / sb);
      }
      std::vector<std::pair<double, double>> pairs;
      for (std::size_t i = 0; i < ref_alpha.size(); ++i)
        if (ref_alpha[i] > 0.99f && u.car_alpha[i] > 0.5f)
          pairs.push_back({Luma(&ref[3 * i]), Luma(&r.car.rgb[3 * i])});
      std::sort(pairs.begin(), pairs.end());
      for (int q = 0; q < 5; ++q) {
        double sa = 0, sb = 0;
        for (std::size_t k = pairs.size() * q / 5; k < pairs.size() * (q + 1) / 5; ++k) {
          sb += pairs[k].first;
          sa += pairs[k].second;
        }
        std::printf("Cycles quintile %d: mean %.4f, ours/Cycles %.3f\n", q, sb / (pairs.size() / 5), sa / sb);
      }
      if (const char* dir = std::getenv("ODVR_RENDER_DEBUG_DIR")) {
        image::SaveImage(std::filesystem::path(dir) / "odvr_car_unshadowed.png", u.car);
        // Side by side, 3x: Cycles | ours | ours unshadowed, around the car.
        const int x0 = 110, y0 = 55, cw = 100, ch = 90, k = 3;
        sphere::EquirectImage crop(3 * cw * k, ch * k);
        for (int y = 0; y < ch * k; ++y)
          for (int x = 0; x < 3 * cw * k; ++x) {
            const int panel = x / (cw * k), sx = x0 + (x % (cw * k)) / k, sy = y0 + y / k;
            const std::size_t i = static_cast<std::size_t>(sy) * w + sx;
            const float* src = panel == 0 ? &ref[3 * i] : panel == 1 ? &r.car.rgb[3 * i] : &u.car.rgb[3 * i];
            for (int c = 0; c < 3; ++c) crop.at(x, y)[c] = src[c];
          }
        image::SaveImage(std::filesystem::path(dir) / "crop.png", crop);
      }
    }
  }

  // Car pixels: covered in both, the reference fully (its edges are anti-aliased).
  double sum_abs = 0, sum_ref = 0, sum_ours = 0, sum_rel = 0;
  int car = 0, ours_only = 0, ref_only = 0;
  std::vector<double> ref_luma;
  for (std::size_t i = 0; i < ref_alpha.size(); ++i)
    if (ref_alpha[i] > 0.99f && r.car_alpha[i] > 0.5f) ref_luma.push_back(Luma(&ref[3 * i]));
  double mean_ref = 0;
  for (double v : ref_luma) mean_ref += v;
  mean_ref /= std::max<std::size_t>(1, ref_luma.size());
  for (std::size_t i = 0; i < ref_alpha.size(); ++i) {
    const bool in_ref = ref_alpha[i] > 0.99f, in_ours = r.car_alpha[i] > 0.5f;
    ours_only += in_ours && ref_alpha[i] < 0.01f;
    ref_only += in_ref && !in_ours;
    if (!(in_ref && in_ours)) continue;
    const double yr = Luma(&ref[3 * i]), yo = Luma(&r.car.rgb[3 * i]);
    sum_abs += std::abs(yo - yr);
    sum_ref += yr;
    sum_ours += yo;
    sum_rel += std::abs(yo - yr) / std::max(yr, 0.05 * mean_ref);
    ++car;
  }
  const double rel_l1 = sum_abs / sum_ref, mean_rel = sum_rel / car, bias = sum_ours / sum_ref;

  // Shadow: the README says the reference's alpha holds the catcher's shadow, but every pixel off
  // the car is exactly 0 in all four channels (Cycles 3.4 with a transparent film leaves the
  // catcher out of the combined pass), so there is nothing to compare the shadow layer with.
  // Counted here so that the test notices when the reference gains one; the comparison then is
  // ratio against 1 − alpha on ground pixels away from both silhouettes.
  const auto near_car = [&](int x, int y) {
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = std::clamp(x + dx, 0, w - 1), yy = std::clamp(y + dy, 0, h - 1);
        const std::size_t j = static_cast<std::size_t>(yy) * w + xx;
        if (r.car_alpha[j] > 0.f || ref_alpha[j] > 0.99f) return true;
      }
    return false;
  };
  double shadow_abs = 0, dark_ref = 0, dark_ours = 0;
  int shadow = 0, ref_nonzero_off_car = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (r.ground_mask[i] < 0.5f || near_car(x, y)) continue;
      ref_nonzero_off_car += ref_alpha[i] > 0.f;
      const double sr = 1.0 - ref_alpha[i], so = Luma(&r.shadow.rgb[3 * i]);
      if (sr > 0.95 && so > 0.95) continue;
      shadow_abs += std::abs(so - sr);
      dark_ref += 1 - sr;
      dark_ours += 1 - so;
      ++shadow;
    }
  std::printf("lighting: %d SGs (%zu peaks); render %dx%d: voxelize %.1f ms, G-buffer %.1f ms, shade %.1f ms\n",
              model.sg_count(), model.peaks.size(), w, h, r.ms.voxelize, r.ms.gbuffer, r.ms.shade);
  std::printf("car: %d px (ours only %d, Cycles only %d); relative L1 %.4f, mean relative %.4f, ours/Cycles %.4f\n",
              car, ours_only, ref_only, rel_l1, mean_rel, bias);
  std::printf(
      "shadow: %d px darker than 0.95 in either; mean |ratio - (1 - alpha)| %.4f; darkness ours %.4f, "
      "Cycles %.4f; reference pixels off the car with alpha > 0: %d\n",
      shadow, shadow_abs / std::max(1, shadow), dark_ours / std::max(1, shadow), dark_ref / std::max(1, shadow),
      ref_nonzero_off_car);
  if (const char* dir = std::getenv("ODVR_RENDER_DEBUG_DIR")) {
    sphere::EquirectImage ref_img(w, h);
    ref_img.rgb = ref;
    image::SaveImage(std::filesystem::path(dir) / "cycles_ref.png", ref_img);
    image::SaveImage(std::filesystem::path(dir) / "odvr_car.png", r.car);
    image::SaveImage(std::filesystem::path(dir) / "odvr_shadow.png", r.shadow);
    image::SaveImage(std::filesystem::path(dir) / "odvr_composite.png", r.composite);
  }
  EXPECT_GT(car, 2000);
  // Same silhouette to the pixel: the pose, camera and axis conventions agree with Blender's.
  EXPECT_LT(ours_only + ref_only, car / 100) << "the silhouettes differ: a pose or camera convention is off";
  // With GGX's residual under the peaks (material::GgxResidualUnderSgLight) and the car's diffuse
  // light on itself (RenderOptions::ambient_bounce); the aim is 0.10.
  EXPECT_LT(rel_l1, 0.16);
  EXPECT_LT(mean_rel, 0.125);
  EXPECT_GT(bias, 0.92);
  EXPECT_LT(bias, 0.99);
  if (ref_nonzero_off_car == 0) {
    std::printf("the reference holds no shadow: shadow accuracy not measured\n");
  } else {
    EXPECT_LT(shadow_abs / std::max(1, shadow), 0.2);
  }
}

}  // namespace
}  // namespace odvr::render
