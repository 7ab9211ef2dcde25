// JSON scene files: compose model files and built-in shapes with transforms and material
// overrides, add lights and named cameras. The format is documented in scenes/README.md.
// Unknown keys are errors (a misspelt key silently ignored is a wrong experiment).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"

namespace lt {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// j's member `key`, or null when it has none (the readers below then say what was expected).
const json& member(const json& j, const char* key) {
  static const json missing;
  const auto it = j.find(key);
  return it == j.end() ? missing : *it;
}

/// Reads one scene file and reports errors as "scene FILE: path.to.key: problem".
class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& where, const std::string& what) const {
    inputError("scene ", source_, ": ", where, ": ", what);
  }

  /// A value as the message quotes it: its JSON, cut short (an error stays one readable line).
  static std::string brief(const json& j) {
    std::string text = j.dump(-1, ' ', false, json::error_handler_t::replace);
    if (text.size() > 60) text = text.substr(0, 57) + "...";
    return text;
  }

  void allowKeys(const json& j, const std::string& where, std::initializer_list<const char*> keys) const {
    if (!j.is_object()) fail(where, "expected an object");
    std::set<std::string> allowed(keys.begin(), keys.end());
    for (auto it = j.begin(); it != j.end(); ++it)
      if (!allowed.count(it.key())) fail(where, cat("unknown key \"", it.key(), "\""));
  }

  float number(const json& j, const std::string& where) const {
    if (!j.is_number()) fail(where, cat("expected a number, got ", brief(j)));
    const double v = j.get<double>();
    if (!std::isfinite(v) || std::abs(v) > 1e30) fail(where, cat("value ", brief(j), " is out of range"));
    return float(v);
  }

  glm::vec3 vec3(const json& j, const std::string& where) const {
    if (!j.is_array() || j.size() != 3) fail(where, cat("expected 3 numbers, got ", brief(j)));
    return {number(j[0], where), number(j[1], where), number(j[2], where)};
  }

  /// A whole number in [lo, hi].
  int integer(const json& j, const std::string& where, int lo, int hi) const {
    if (!j.is_number()) fail(where, cat("expected a whole number, got ", brief(j)));
    const double v = j.get<double>();
    if (!(v >= lo && v <= hi) || v != std::floor(v)) fail(where, cat("value ", brief(j), " is not a whole number in [", lo, ", ", hi, "]"));
    return int(v);
  }

  /// A colour or intensity: one number (grey) or three, none negative.
  glm::vec3 colour(const json& j, const std::string& where) const {
    const glm::vec3 c = j.is_number() ? glm::vec3(number(j, where)) : vec3(j, where);
    if (c.x < 0.0f || c.y < 0.0f || c.z < 0.0f) fail(where, cat("value ", brief(j), " is negative"));
    return c;
  }

  float unitInterval(const json& j, const std::string& where) const {
    const float v = number(j, where);
    if (v < 0.0f || v > 1.0f) fail(where, cat("value ", v, " is not in [0, 1]"));
    return v;
  }

  Material material(const json& j, const std::string& name, const std::string& where) const {
    allowKeys(j, where, {"albedo", "specular", "shininess", "mirror", "transmission", "ior"});
    Material m;
    m.name = name;
    if (j.contains("albedo")) m.albedo = colour(j["albedo"], where + ".albedo");
    if (j.contains("specular")) m.specular = unitInterval(j["specular"], where + ".specular");
    if (j.contains("shininess")) m.shininess = number(j["shininess"], where + ".shininess");
    if (j.contains("mirror")) m.mirror = unitInterval(j["mirror"], where + ".mirror");
    if (j.contains("transmission")) m.transmission = unitInterval(j["transmission"], where + ".transmission");
    if (j.contains("ior")) {
      m.ior = number(j["ior"], where + ".ior");
      if (m.ior < 1.0f || m.ior > 4.0f) fail(where + ".ior", cat("value ", m.ior, " is not in [1, 4]"));
    }
    if (glm::any(glm::lessThan(m.albedo, glm::vec3(0.0f))) || glm::any(glm::greaterThan(m.albedo, glm::vec3(1.0f))))
      fail(where + ".albedo", "components must be in [0, 1]");
    if (m.shininess < 1.0f) fail(where + ".shininess", cat("value ", m.shininess, " must be at least 1"));
    return m;
  }

  glm::mat4 transform(const json& j, const std::string& where) const {
    allowKeys(j, where, {"translate", "rotate", "scale", "matrix"});
    if (j.contains("matrix")) {
      if (j.size() != 1) fail(where, "\"matrix\" excludes translate/rotate/scale");
      const json& a = j["matrix"];
      if (!a.is_array() || a.size() != 16) fail(where + ".matrix", "expected 16 numbers (row-major)");
      glm::mat4 m;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) m[c][r] = number(a[size_t(r * 4 + c)], where + ".matrix");
      return m;
    }
    glm::mat4 m(1.0f);
    if (j.contains("translate")) m = glm::translate(m, vec3(j["translate"], where + ".translate"));
    if (j.contains("rotate")) {  // Euler angles in degrees, applied about X, then Y, then Z
      const glm::vec3 r = vec3(j["rotate"], where + ".rotate");
      m = glm::rotate(m, glm::radians(r.z), {0, 0, 1});
      m = glm::rotate(m, glm::radians(r.y), {0, 1, 0});
      m = glm::rotate(m, glm::radians(r.x), {1, 0, 0});
    }
    if (j.contains("scale")) {
      const glm::vec3 s = j["scale"].is_number() ? glm::vec3(number(j["scale"], where + ".scale"))
                                                 : vec3(j["scale"], where + ".scale");
      if (s.x == 0.0f || s.y == 0.0f || s.z == 0.0f) fail(where + ".scale", "must not be zero");
      m = glm::scale(m, s);
    }
    return m;
  }

  /// A built-in shape; its own complaint ("box: max must exceed min …") names the file and object.
  template <class Make>
  Scene shape(const std::string& where, Make&& make) const {
    try {
      return make();
    } catch (const InputError& e) {
      fail(where, e.what());
    }
  }

  std::string string(const json& j, const std::string& where) const {
    if (!j.is_string()) fail(where, cat("expected a string, got ", brief(j)));
    return j.get<std::string>();
  }

 private:
  std::string source_;
};

}  // namespace

Scene parseJsonScene(const std::string& text, const std::string& baseDir, const std::string& source) {
  // A scene file is a handful of levels deep. Deeper nesting is refused while parsing: the
  // parser is iterative, but copying or printing a value nested 100 000 deep recurses off the
  // stack (found by a sweep of hand-written scene files).
  constexpr int kMaxDepth = 64;
  if (const size_t nul = text.find('\0'); nul != std::string::npos)
    inputError("scene ", source, ": malformed JSON: a NUL byte at offset ", nul);
  json root;
  try {
    root = json::parse(text, [&](int depth, json::parse_event_t, json&) {
      if (depth > kMaxDepth) inputError("scene ", source, ": malformed JSON: nested deeper than ", kMaxDepth, " levels");
      return true;
    });
  } catch (const json::exception& e) {
    // parse_error carries "at line L, column C"; out_of_range is a number beyond double (1e999,
    // found by fuzz/fuzz_json_scene.cpp); both are bad input.
    std::string what = e.what();
    const auto pos = what.find("parse error");
    if (pos != std::string::npos) what = what.substr(pos);
    if (what.size() > 160) what = what.substr(0, 157) + "...";  // "last read: '…'" quotes the token, however long
    inputError("scene ", source, ": malformed JSON: ", what);
  }
  const Reader r(source);
  r.allowKeys(root, "top level", {"name", "environment", "materials", "objects", "lights", "cameras"});

  std::map<std::string, Material> named;
  if (root.contains("materials")) {
    const json& mats = root["materials"];
    if (!mats.is_object()) r.fail("materials", "expected an object of named materials");
    for (auto it = mats.begin(); it != mats.end(); ++it)
      named[it.key()] = r.material(it.value(), it.key(), "materials." + it.key());
  }
  auto lookup = [&](const std::string& name, const std::string& where) {
    auto it = named.find(name);
    if (it == named.end()) r.fail(where, cat("unknown material \"", name, "\""));
    return it->second;
  };

  Scene scene;
  scene.name = root.contains("name") ? r.string(root["name"], "name") : fs::path(source).stem().string();
  if (root.contains("environment")) scene.environment = r.colour(root["environment"], "environment");

  if (!root.contains("objects") || !root["objects"].is_array() || root["objects"].empty())
    r.fail("objects", "expected a non-empty array of objects");
  const json& objects = root["objects"];
  for (size_t i = 0; i < objects.size(); ++i) {
    const std::string where = cat("objects[", i, "]");
    const json& o = objects[i];
    r.allowKeys(o, where, {"model", "box", "sphere", "quad", "transform", "material", "materials", "override", "name"});
    const glm::mat4 m = o.contains("transform") ? r.transform(o["transform"], where + ".transform") : glm::mat4(1.0f);
    Scene part;
    int kinds = 0;
    if (o.contains("model")) {
      ++kinds;
      fs::path p = r.string(o["model"], where + ".model");
      if (p.is_relative()) p = fs::path(baseDir) / p;
      part = loadModel(p.string(), m);
    }
    if (o.contains("box")) {
      ++kinds;
      const json& b = o["box"];
      r.allowKeys(b, where + ".box", {"min", "max"});
      const glm::vec3 lo = r.vec3(member(b, "min"), where + ".box.min");
      const glm::vec3 hi = r.vec3(member(b, "max"), where + ".box.max");
      part = r.shape(where + ".box", [&] { return makeBox(lo, hi); });
      transformScene(part, m);
    }
    if (o.contains("sphere")) {
      ++kinds;
      const json& s = o["sphere"];
      r.allowKeys(s, where + ".sphere", {"center", "radius", "segments"});
      const int seg = s.contains("segments") ? r.integer(s["segments"], where + ".sphere.segments", 3, 4096) : 48;
      const glm::vec3 centre = s.contains("center") ? r.vec3(s["center"], where + ".sphere.center") : glm::vec3(0.0f);
      const float radius = r.number(member(s, "radius"), where + ".sphere.radius");
      part = r.shape(where + ".sphere", [&] { return makeSphere(centre, radius, seg); });
      transformScene(part, m);
    }
    if (o.contains("quad")) {
      ++kinds;
      const json& q = o["quad"];
      r.allowKeys(q, where + ".quad", {"corner", "u", "v"});
      const glm::vec3 corner = r.vec3(member(q, "corner"), where + ".quad.corner");
      const glm::vec3 u = r.vec3(member(q, "u"), where + ".quad.u"), v = r.vec3(member(q, "v"), where + ".quad.v");
      part = r.shape(where + ".quad", [&] { return makeQuad(corner, u, v); });
      transformScene(part, m);
    }
    if (kinds != 1) r.fail(where, "needs exactly one of \"model\", \"box\", \"sphere\", \"quad\"");
    if (o.contains("material")) {
      const Material mat = lookup(r.string(o["material"], where + ".material"), where + ".material");
      part.materials.assign(1, mat);
      part.triMaterial.assign(part.triangles.size(), 0);
    }
    if (o.contains("materials")) {  // override by the model's own material names
      const json& ov = o["materials"];
      if (!ov.is_object()) r.fail(where + ".materials", "expected an object {model material: scene material}");
      for (auto it = ov.begin(); it != ov.end(); ++it) {
        const Material mat = lookup(r.string(it.value(), where + ".materials." + it.key()), where + ".materials." + it.key());
        bool found = false;
        for (Material& pm : part.materials)
          if (pm.name == it.key()) pm = mat, found = true;
        if (!found) r.fail(where + ".materials", cat("the model has no material \"", it.key(), "\""));
      }
    }
    if (o.contains("override")) {  // change some attributes of every material, keep the rest
      const json& ov = o["override"];
      const std::string w = where + ".override";
      r.allowKeys(ov, w, {"albedo", "specular", "shininess", "mirror", "transmission", "ior"});
      const Material probe = r.material(ov, "override", w);  // validates the values
      for (Material& pm : part.materials) {
        if (ov.contains("albedo")) pm.albedo = probe.albedo;
        if (ov.contains("specular")) pm.specular = probe.specular;
        if (ov.contains("shininess")) pm.shininess = probe.shininess;
        if (ov.contains("mirror")) pm.mirror = probe.mirror;
        if (ov.contains("transmission")) pm.transmission = probe.transmission;
        if (ov.contains("ior")) pm.ior = probe.ior;
      }
    }
    scene.append(part);
  }

  if (root.contains("lights")) {
    const json& lights = root["lights"];
    if (!lights.is_array()) r.fail("lights", "expected an array");
    for (size_t i = 0; i < lights.size(); ++i) {
      const std::string where = cat("lights[", i, "]");
      r.allowKeys(lights[i], where, {"position", "intensity"});
      PointLight l;
      l.position = r.vec3(member(lights[i], "position"), where + ".position");
      if (lights[i].contains("intensity")) l.intensity = r.colour(lights[i]["intensity"], where + ".intensity");
      scene.lights.push_back(l);
    }
  }
  if (root.contains("cameras")) {
    const json& cams = root["cameras"];
    if (!cams.is_array()) r.fail("cameras", "expected an array");
    // The file's own cameras come before any its models brought (a glTF's camera node): the
    // default view (the first camera) is then the one the scene's author named, not whatever
    // the model's exporter left in it.
    std::vector<CameraDesc> own;
    for (size_t i = 0; i < cams.size(); ++i) {
      const std::string where = cat("cameras[", i, "]");
      const json& c = cams[i];
      r.allowKeys(c, where, {"name", "eye", "target", "up", "fov", "near", "far"});
      CameraDesc d;
      d.name = c.contains("name") ? r.string(c["name"], where + ".name") : cat("camera", i);
      d.eye = r.vec3(member(c, "eye"), where + ".eye");
      d.target = r.vec3(member(c, "target"), where + ".target");
      if (c.contains("up")) d.up = r.vec3(c["up"], where + ".up");
      if (d.eye == d.target) r.fail(where, "eye and target coincide");
      if (d.up == glm::vec3(0.0f)) r.fail(where + ".up", "must not be zero");
      if (c.contains("fov")) d.fovY = r.number(c["fov"], where + ".fov");
      if (c.contains("near")) d.near = r.number(c["near"], where + ".near");
      if (c.contains("far")) d.far = r.number(c["far"], where + ".far");
      if (!(d.fovY > 0.0f && d.fovY < 180.0f)) r.fail(where + ".fov", cat("value ", d.fovY, " is not in (0, 180)"));
      if (d.near < 0.0f || d.far < 0.0f || (d.far > 0.0f && d.far <= d.near))
        r.fail(where, cat("near ", d.near, " and far ", d.far, " must satisfy 0 < near < far"));
      own.push_back(d);
    }
    scene.cameras.insert(scene.cameras.begin(), own.begin(), own.end());
  }
  scene.finalize(source);
  return scene;
}

Scene loadJsonScene(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) inputError("scene ", path, ": file not found");
  std::ifstream in(path, std::ios::binary);
  if (!in) inputError("scene ", path, ": cannot open");
  std::stringstream ss;
  ss << in.rdbuf();
  return parseJsonScene(ss.str(), fs::path(path).parent_path().string(), path);
}

Scene loadScene(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower((unsigned char)c));
  Scene scene = ext == ".json" ? loadJsonScene(path) : loadModel(path);
  recentre(scene);
  return scene;
}

}  // namespace lt
