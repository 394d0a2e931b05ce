#include "capture/rig.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"

namespace odvr::capture {
namespace {

using nlohmann::json;

class Parser {
 public:
  explicit Parser(std::filesystem::path path) : path_(std::move(path)) {}

  [[noreturn]] void Fail(const std::string& reason) const { throw Error(path_.string(), reason); }

  double Number(const json& j, const std::string& key, const std::string& where) const {
    if (!j.contains(key)) Fail(where + ": missing \"" + key + "\"");
    const json& v = j.at(key);
    if (!v.is_number() || !std::isfinite(v.get<double>())) Fail(where + ": \"" + key + "\" is not a finite number");
    return v.get<double>();
  }

  int PositiveInt(const json& j, const std::string& key, const std::string& where) const {
    const double v = Number(j, key, where);
    if (v != std::floor(v) || v <= 0 || v > 1e6) Fail(where + ": \"" + key + "\" must be a positive integer");
    return static_cast<int>(v);
  }

  std::vector<double> Numbers(const json& j, const std::string& key, const std::string& where, std::size_t min_count,
                              std::size_t max_count) const {
    if (!j.contains(key)) Fail(where + ": missing \"" + key + "\"");
    const json& v = j.at(key);
    if (!v.is_array()) Fail(where + ": \"" + key + "\" is not an array");
    std::vector<double> out;
    for (const auto& x : v) {
      if (!x.is_number() || !std::isfinite(x.get<double>()))
        Fail(where + ": \"" + key + "\" holds something that is not a finite number");
      out.push_back(x.get<double>());
    }
    if (out.size() < min_count || out.size() > max_count)
      Fail(where + ": \"" + key + "\" has " + std::to_string(out.size()) + " values, expected " +
           (min_count == max_count ? std::to_string(min_count)
                                   : std::to_string(min_count) + " to " + std::to_string(max_count)));
    return out;
  }

  Eigen::Matrix4d Transform(const json& cam, const std::string& where) const {
    const char* key = cam.contains("T_rig_cam") ? "T_rig_cam" : "T_cam_rig";
    if (!cam.contains(key)) Fail(where + ": missing \"T_rig_cam\"");
    const json& t = cam.at(key);
    Eigen::Matrix4d m;
    bool shape_ok = t.is_array() && t.size() == 4;
    for (int r = 0; shape_ok && r < 4; ++r) {
      shape_ok = t[r].is_array() && t[r].size() == 4;
      for (int c = 0; shape_ok && c < 4; ++c) {
        shape_ok = t[r][c].is_number() && std::isfinite(t[r][c].get<double>());
        if (shape_ok) m(r, c) = t[r][c].get<double>();
      }
    }
    if (!shape_ok) Fail(where + ": \"" + key + "\" is not a 4x4 matrix of finite numbers");
    if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9)
      Fail(where + ": \"" + key + "\" last row is not [0, 0, 0, 1]");
    const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
    // Calibration files print rotations to ~9 digits; anything further off is not a rotation.
    if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-6 || r.determinant() < 0)
      Fail(where + ": \"" + key + "\" rotation is not orthonormal with determinant +1");
    if (std::string(key) == "T_cam_rig") {
      Eigen::Matrix4d inv = Eigen::Matrix4d::Identity();
      inv.topLeftCorner<3, 3>() = r.transpose();
      inv.topRightCorner<3, 1>() = -r.transpose() * m.topRightCorner<3, 1>();
      m = inv;
    }
    return m;
  }

  RigCamera Camera(const json& cam, const std::string& where) const {
    if (!cam.is_object()) Fail(where + ": not a JSON object");
    RigCamera out;
    out.name = cam.contains("name") && cam["name"].is_string() ? cam["name"].get<std::string>() : where;
    if (cam.contains("image_dir") && cam["image_dir"].is_string()) out.image_dir = cam["image_dir"].get<std::string>();
    if (cam.contains("camera_model")) {
      // Kalibr-like.
      const std::string model = String(cam, "camera_model", where);
      const std::string dist = cam.contains("distortion_model") ? String(cam, "distortion_model", where) : "none";
      const auto res = Numbers(cam, "resolution", where, 2, 2);
      const int w = static_cast<int>(res[0]), h = static_cast<int>(res[1]);
      if (res[0] != w || res[1] != h || w <= 0 || h <= 0)
        Fail(where + ": \"resolution\" must be two positive integers");
      if (model == "omni-equirect" || model == "equirectangular") {
        out.model = CameraModel::Equirectangular(w, h);
      } else {
        const auto in = Numbers(cam, "intrinsics", where, 4, 4);
        if (!(in[0] > 0 && in[1] > 0)) Fail(where + ": focal lengths in \"intrinsics\" must be positive");
        const bool fisheye = model == "fisheye" || (model == "pinhole" && dist == "equidistant");
        if (model != "pinhole" && model != "fisheye")
          Fail(where + ": unknown camera_model \"" + model + "\" (pinhole, fisheye, omni-equirect)");
        if (fisheye) {
          if (dist != "equidistant" && dist != "none" && dist != "kannala_brandt")
            Fail(where + ": fisheye needs distortion_model \"equidistant\", not \"" + dist + "\"");
          std::array<double, 4> k{};
          if (cam.contains("distortion_coeffs")) {
            const auto d = Numbers(cam, "distortion_coeffs", where, 0, 4);
            std::copy(d.begin(), d.end(), k.begin());
          }
          out.model = CameraModel::Fisheye(w, h, in[0], in[1], in[2], in[3], k);
        } else {
          if (dist != "radtan" && dist != "none" && dist != "plumb_bob")
            Fail(where + ": pinhole needs distortion_model \"radtan\" or \"none\", not \"" + dist + "\"");
          // Kalibr's radtan holds k1, k2, p1, p2; OpenCV's fifth coefficient k3 is accepted too.
          std::array<double, 5> k{};
          if (cam.contains("distortion_coeffs")) {
            const auto d = Numbers(cam, "distortion_coeffs", where, 0, 5);
            std::copy(d.begin(), d.end(), k.begin());
          }
          out.model = CameraModel::Pinhole(w, h, in[0], in[1], in[2], in[3], k);
        }
      }
    } else {
      // The datasets' rig.json.
      const std::string model = String(cam, "model", where);
      const int w = PositiveInt(cam, "width", where), h = PositiveInt(cam, "height", where);
      if (model == "equirectangular") {
        out.model = CameraModel::Equirectangular(w, h);
      } else {
        const double fx = Number(cam, "fx", where), fy = Number(cam, "fy", where);
        if (!(fx > 0 && fy > 0)) Fail(where + ": \"fx\" and \"fy\" must be positive");
        const double cx = Number(cam, "cx", where), cy = Number(cam, "cy", where);
        auto opt = [&](const char* k) { return cam.contains(k) ? Number(cam, k, where) : 0.0; };
        if (model == "opencv_fisheye" || model == "fisheye" || model == "kannala_brandt") {
          out.model = CameraModel::Fisheye(w, h, fx, fy, cx, cy, {opt("k1"), opt("k2"), opt("k3"), opt("k4")});
        } else if (model == "opencv" || model == "pinhole") {
          out.model =
              CameraModel::Pinhole(w, h, fx, fy, cx, cy, {opt("k1"), opt("k2"), opt("p1"), opt("p2"), opt("k3")});
        } else {
          Fail(where + ": unknown model \"" + model + "\" (opencv_fisheye, opencv, pinhole, equirectangular)");
        }
      }
    }
    out.rig_from_cam = Transform(cam, where);
    return out;
  }

  std::string String(const json& j, const std::string& key, const std::string& where) const {
    if (!j.contains(key) || !j.at(key).is_string()) Fail(where + ": missing string \"" + key + "\"");
    return j.at(key).get<std::string>();
  }

 private:
  std::filesystem::path path_;
};

}  // namespace

Rig ParseRig(const std::string& text, const std::filesystem::path& path) {
  const Parser p(path);
  json root;
  try {
    root = json::parse(text);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number beyond double's range
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    p.Fail("not valid JSON (" + what + ")");
  }
  if (!root.is_object()) p.Fail("not a JSON object");
  Rig rig;
  rig.path = path;
  if (root.contains("rig_height_m")) {
    rig.height_m = p.Number(root, "rig_height_m", "rig");
    if (rig.height_m < 0) p.Fail("\"rig_height_m\" is negative");
  }

  // Cameras by index: "cameras"[i] (with an optional "id") or "camN" keys. A gap in the
  // numbering is a camera missing from the file, never silently renumbered.
  std::map<int, RigCamera> by_index;
  if (root.contains("cameras")) {
    const json& cams = root["cameras"];
    if (!cams.is_array()) p.Fail("\"cameras\" is not an array");
    for (std::size_t i = 0; i < cams.size(); ++i) {
      int id = static_cast<int>(i);
      if (cams[i].is_object() && cams[i].contains("id")) {
        const double v = p.Number(cams[i], "id", "camera " + std::to_string(i));
        if (v != std::floor(v) || v < 0 || v > 1000) p.Fail("camera " + std::to_string(i) + ": bad \"id\"");
        id = static_cast<int>(v);
      }
      if (by_index.count(id)) p.Fail("camera id " + std::to_string(id) + " appears twice");
      by_index.emplace(id, p.Camera(cams[i], "camera " + std::to_string(id)));
    }
  } else {
    for (auto it = root.begin(); it != root.end(); ++it) {
      const std::string& key = it.key();
      if (key.size() > 3 && key.rfind("cam", 0) == 0 &&
          std::all_of(key.begin() + 3, key.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); })) {
        const int id = std::stoi(key.substr(3));
        RigCamera cam = p.Camera(it.value(), key);
        if (!it.value().contains("name")) cam.name = key;
        by_index.emplace(id, std::move(cam));
      }
    }
  }
  if (by_index.empty()) p.Fail("no cameras (expected \"cameras\": [...] or \"cam0\", \"cam1\", ...)");
  int expected = 0;
  for (auto& [id, cam] : by_index) {
    if (id != expected) {
      std::string ids;
      for (const auto& [i, c] : by_index) {
        if (!ids.empty()) ids += ',';  // not `"," + to_string`: GCC 12's -O3 -Wrestrict false positive
        ids += std::to_string(i);
      }
      p.Fail("camera " + std::to_string(expected) + " is missing (cameras numbered " + ids + ")");
    }
    rig.cameras.push_back(std::move(cam));
    ++expected;
  }
  if (root.contains("camera_count")) {
    const double n = p.Number(root, "camera_count", "rig");
    if (n != rig.camera_count())
      p.Fail("\"camera_count\" says " + std::to_string(static_cast<int>(n)) + " cameras but " +
             std::to_string(rig.camera_count()) + " are described");
  }
  return rig;
}

Rig LoadRig(const std::filesystem::path& path) {
  if (!std::filesystem::is_regular_file(path)) throw Error(path.string(), "no such rig file");
  std::ifstream in(path);
  if (!in) throw Error(path.string(), "cannot read the rig file");
  std::stringstream ss;
  ss << in.rdbuf();
  return ParseRig(ss.str(), path);
}

void SaveRig(const std::filesystem::path& path, const Rig& rig) {
  json root;
  root["rig_height_m"] = rig.height_m;
  root["camera_count"] = rig.camera_count();
  for (int i = 0; i < rig.camera_count(); ++i) {
    const RigCamera& c = rig.cameras[static_cast<std::size_t>(i)];
    const CameraModel& m = c.model;
    json j;
    j["name"] = c.name;
    j["resolution"] = {m.width(), m.height()};
    switch (m.type()) {
      case CameraModelType::kPinhole:
        j["camera_model"] = "pinhole";
        j["distortion_model"] = "radtan";
        break;
      case CameraModelType::kFisheye:
        j["camera_model"] = "fisheye";
        j["distortion_model"] = "equidistant";
        break;
      case CameraModelType::kEquirectangular:
        j["camera_model"] = "omni-equirect";
        j["distortion_model"] = "none";
        break;
    }
    j["intrinsics"] = {m.fx(), m.fy(), m.cx(), m.cy()};
    j["distortion_coeffs"] = m.distortion();
    json t = json::array();
    for (int r = 0; r < 4; ++r)
      t.push_back({c.rig_from_cam(r, 0), c.rig_from_cam(r, 1), c.rig_from_cam(r, 2), c.rig_from_cam(r, 3)});
    j["T_rig_cam"] = t;
    if (!c.image_dir.empty()) j["image_dir"] = c.image_dir;
    root["cam" + std::to_string(i)] = j;
  }
  WriteTextAtomically(path, root.dump(1) + "\n");
}

}  // namespace odvr::capture
