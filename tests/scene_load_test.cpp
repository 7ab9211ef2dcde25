// Scene loading: JSON composition, built-in shapes, and every kind of bad input.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <random>


#include <assimp/material.h>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"
#include "layertrace/util/warning.h"
#include "test_util.h"

namespace lt {
namespace {

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(SceneJson, ComposesShapesMaterialsLightsCameras) {
  const Scene s = parseJsonScene(R"({
    "materials": {"m": {"albedo": [0.5, 0.25, 1], "mirror": 0.5, "transmission": 0.2, "ior": 1.33}},
    "objects": [
      {"box": {"min": [0,0,0], "max": [1,2,3]}, "material": "m", "transform": {"translate": [10, 0, 0]}},
      {"sphere": {"center": [0,0,0], "radius": 2, "segments": 8}},
      {"quad": {"corner": [0,0,0], "u": [1,0,0], "v": [0,1,0]}}
    ],
    "lights": [{"position": [1,2,3], "intensity": [4,5,6]}],
    "cameras": [{"name": "c", "eye": [0,0,5], "target": [0,0,0], "fov": 40}]
  })", ".", "inline");
  // box 12; sphere with 8 segments: 5 rings × 8 × 2 minus the 2 × 8 degenerate pole triangles; quad 2.
  EXPECT_EQ(s.triangles.size(), 12u + 64u + 2u);
  const Bounds b = s.bounds();
  EXPECT_FLOAT_EQ(b.hi.x, 11.0f);
  EXPECT_NEAR(b.lo.x, -2.0f * std::sin(0.6f * 3.14159265f), 1e-5f);  // the widest ring of 5
  EXPECT_FLOAT_EQ(b.hi.z, 3.0f);
  ASSERT_EQ(s.lights.size(), 1u);
  EXPECT_EQ(s.lights[0].intensity, glm::vec3(4, 5, 6));
  ASSERT_EQ(s.cameras.size(), 1u);
  EXPECT_EQ(s.cameras[0].fovY, 40.0f);
  EXPECT_EQ(s.materials[s.triMaterial[0]].mirror, 0.5f);
  EXPECT_EQ(s.materials[s.triMaterial[0]].ior, 1.33f);
  for (const glm::vec3& n : s.normals) EXPECT_NEAR(glm::length(n), 1.0f, 1e-5f);
}

TEST(SceneJson, OverrideChangesOnlyTheNamedAttributes) {
  const Scene s = parseJsonScene(R"({
    "materials": {"m": {"albedo": [0.5, 0.25, 1], "specular": 0.3}},
    "objects": [{"box": {"min": [0,0,0], "max": [1,1,1]}, "material": "m", "override": {"mirror": 0.4}}]
  })", ".", "inline");
  EXPECT_EQ(s.materials[0].mirror, 0.4f);
  EXPECT_EQ(s.materials[0].specular, 0.3f);
  EXPECT_EQ(s.materials[0].albedo, glm::vec3(0.5f, 0.25f, 1.0f));
  EXPECT_THROW(parseJsonScene(R"({"objects": [{"box": {"min": [0,0,0], "max": [1,1,1]}, "override": {"mirror": 3}}]})", ".", "x"),
               InputError);
}

TEST(SceneJson, ErrorsNameTheInputAndValue) {
  auto err = [](const std::string& text) { return errorOf([&] { parseJsonScene(text, ".", "x.json"); }); };
  EXPECT_NE(err("{\"objects\": [\n {\"box\": }]}").find("line 2, column"), std::string::npos) << err("{\"objects\": [\n {\"box\": }]}");
  EXPECT_NE(err(R"({"objects": [{"box": {"min": [0,0,0], "max": [1,1,1]}, "colour": 1}]})").find("unknown key \"colour\""), std::string::npos);
  EXPECT_NE(err(R"({"objects": [{"box": {"min": [0,0,0], "max": [1,1,1]}, "material": "nope"}]})").find("unknown material \"nope\""), std::string::npos);
  EXPECT_NE(err(R"({"objects": []})").find("objects"), std::string::npos);
  EXPECT_NE(err(R"({"objects": [{"sphere": {"radius": -1}}]})").find("radius -1"), std::string::npos);
  EXPECT_NE(err(R"({"materials": {"m": {"mirror": 2}}, "objects": [{"sphere": {"radius": 1}}]})").find("value 2 is not in [0, 1]"), std::string::npos);
  EXPECT_NE(err(R"({"objects": [{"model": "missing.obj"}]})").find("missing.obj: file not found"), std::string::npos);
  EXPECT_NE(err(R"({"objects": [{"sphere": {"radius": 1}}], "cameras": [{"eye": [0,0,1], "target": [0,0,0], "fov": 0}]})").find("fov"), std::string::npos);
  EXPECT_NE(err("").find("x.json: malformed JSON"), std::string::npos);
  // Found by a sweep of hand-written scene files: each refused by name.
  EXPECT_NE(err(R"({"objects": [{"sphere": {"radius": 1, "segments": 3.9}}]})").find("segments: value 3.9 is not a whole number"), std::string::npos);
  EXPECT_NE(err(R"({"objects": [{"sphere": {"radius": 1, "segments": 1e30}}]})").find("segments: value 1e+30"), std::string::npos);
  EXPECT_NE(err(R"({"objects": [{"box": {"min": [0,0,0], "max": [1,0,1]}}]})").find("x.json: objects[0].box: box: max must exceed min"), std::string::npos);
  EXPECT_NE(err(R"({"objects": [{"sphere": {"radius": 1}}], "cameras": [{"eye": [1,2,3], "target": [1,2,3]}]})").find("cameras[0]: eye and target coincide"),
            std::string::npos);
  EXPECT_NE(err(R"({"objects": [{"sphere": {"radius": 1}}], "lights": [{"position": [0,0,0], "intensity": -5}]})").find("lights[0].intensity: value -5 is negative"),
            std::string::npos);
  EXPECT_NE(err(R"({"environment": [-1, 0, 0], "objects": [{"sphere": {"radius": 1}}]})").find("environment"), std::string::npos);
  EXPECT_NE(err(R"({"objects": [{"box": {"min": [0,0,0], "max": [1,1,1]}}]})" + std::string(1, '\0') + "junk").find("a NUL byte at offset"), std::string::npos);
  // Nested 100 000 deep: refused while parsing (copying or printing it recursed off the stack).
  const std::string deep = R"({"objects": [{"box": {"min": )" + std::string(100000, '[') + std::string(100000, ']') + R"(, "max": [1,1,1]}}]})";
  EXPECT_NE(err(deep).find("nested deeper than 64 levels"), std::string::npos);
  // A long value is quoted cut short: the message stays one readable line.
  EXPECT_LT(err(R"({"objects": [{"box": {"min": [)" + std::string(20000, '1') + R"(], "max": [1,1,1]}}]})").size(), 200u);
}

// A mirroring transform (negative determinant) keeps each triangle's front face outside: the
// winding is reversed with the positions (before, a mirrored box was captured inside out with
// --front-faces-only). Built-in shapes and models (assimp's node transforms) alike.
TEST(SceneJson, MirroringTransformsKeepFrontFacesOutward) {
  auto outward = [](const Scene& s) {  // triangles whose winding normal points away from the centre
    const glm::vec3 c = s.bounds().center();
    size_t n = 0;
    for (const glm::uvec3& t : s.triangles) {
      const glm::vec3 a = s.positions[t.x], b = s.positions[t.y], d = s.positions[t.z];
      n += glm::dot(glm::cross(b - a, d - a), (a + b + d) / 3.0f - c) > 0.0f;
    }
    return n;
  };
  test::TempDir dir;  // an octahedron, counter-clockwise seen from outside
  std::ofstream(dir / "octahedron.obj") << "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
                                           "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";
  for (const char* transform : {R"({"scale": [1, 1, 1]})", R"({"scale": [-1, 1, 1]})", R"({"scale": [-2, -3, -1]})",
                                R"({"matrix": [1,0,0,0, 0,1,0,0, 0,0,-1,0, 0,0,0,1]})", R"({"scale": [-1, -1, 1]})"}) {
    SCOPED_TRACE(transform);
    const Scene box = parseJsonScene(std::string(R"({"objects": [{"box": {"min": [-1,-1,-1], "max": [1,1,1]}, "transform": )") + transform + "}]}", ".", "x.json");
    EXPECT_EQ(outward(box), box.triangles.size());
    const Scene model = parseJsonScene(std::string(R"({"objects": [{"model": "octahedron.obj", "transform": )") + transform + "}]}", dir.path.string(), "x.json");
    ASSERT_EQ(model.triangles.size(), 8u);
    EXPECT_EQ(outward(model), 8u);
  }
}

// A scene file's cameras come first, before the cameras of the models it loads: the default
// view (the first camera) is the one the file names; a glTF camera sits at its node.
// (2CylinderEngine.glb carries its own camera, and `compare scenes/engine.json` without
// --camera looked through it instead of "interior".)
TEST(SceneJson, OwnCamerasComeBeforeTheModelsCameras) {
  test::TempDir dir;
  test::writeTriangleWithCamera(dir / "tri.gltf");
  const Scene model = loadScene(dir / "tri.gltf");
  ASSERT_EQ(model.cameras.size(), 1u) << "the model's camera is loaded (else this test shows nothing)";
  // at its node, looking down the node's −z (assimp 5.2 also put the node's translation in the
  // camera's own position: the eye was at z = 20)
  EXPECT_EQ(model.cameras[0].eye, glm::vec3(0, 0, 10));
  EXPECT_EQ(model.cameras[0].target, glm::vec3(0, 0, 9));
  const Scene s = parseJsonScene(R"({"objects": [{"model": "tri.gltf"}],
    "cameras": [{"name": "mine", "eye": [0, 0, 5], "target": [0, 0, 0]}, {"name": "second", "eye": [0, 1, 5], "target": [0, 0, 0]}]})",
                                 dir.path.string(), "x.json");
  ASSERT_EQ(s.cameras.size(), 3u);
  EXPECT_EQ(s.cameras[0].name, "mine");
  EXPECT_EQ(s.cameras[1].name, "second");
  EXPECT_EQ(s.cameras[2].name, model.cameras[0].name);
}

TEST(SceneLoad, MissingAndEmptyFiles) {
  test::TempDir dir;
  EXPECT_NE(errorOf([&] { loadScene(dir / "nothing.obj"); }).find("file not found"), std::string::npos);
  std::ofstream(dir / "empty.obj") << "# nothing here\n";
  const std::string e = errorOf([&] { loadScene(dir / "empty.obj"); });
  EXPECT_NE(e.find("empty.obj"), std::string::npos) << e;
  std::ofstream(dir / "points.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\np 1\n";
  EXPECT_NE(errorOf([&] { loadScene(dir / "points.obj"); }).find("points.obj"), std::string::npos);
}

TEST(SceneLoad, RandomBytesAreInputErrorsNeverCrashes) {
  test::TempDir dir;
  std::mt19937_64 rng(test::testSeed());
  for (const char* ext : {".obj", ".glb", ".json", ".ply", ".dae", ".ifc"}) {
    for (int trial = 0; trial < 5; ++trial) {
      std::string bytes(size_t(64 + trial * 997), '\0');
      for (char& c : bytes) c = char(rng() & 0xFF);
      if (trial == 1 && std::string(ext) == ".glb") bytes.replace(0, 4, "glTF");  // a plausible header
      const std::string path = dir / (std::string("random") + std::to_string(trial) + ext);
      std::ofstream(path, std::ios::binary) << bytes;
      try {
        // Some parsers accept noise; then it must still be a valid scene (finalize() checks
        // indices and finite positions).
        const Scene s = loadScene(path);
        EXPECT_GT(s.triangleCount(), 0u) << path;
        EXPECT_GT(s.bounds().diagonal(), 0.0f) << path;
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      }
    }
  }
}

TEST(SceneLoad, TransformsApplyToNormalsAndCameras) {
  Scene s = makeBox({0, 0, 0}, {1, 1, 1});
  s.cameras.push_back(CameraDesc{"c", {0, 0, 5}, {0, 0, 0}});
  transformScene(s, glm::mat4(2.0f, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3, 0, 0, 1));  // scale x by 2, move x by 3
  EXPECT_FLOAT_EQ(s.bounds().hi.x, 5.0f);
  EXPECT_FLOAT_EQ(s.cameras[0].eye.x, 3.0f);
  for (const glm::vec3& n : s.normals) EXPECT_NEAR(glm::length(n), 1.0f, 1e-6f);
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// A scene whose coordinates overflow float arithmetic is refused with one line naming the
// input and the magnitude, not a derived symptom (an infinite camera far plane).
TEST(SceneLoad, CoordinatesThatOverflowFloatArithmeticAreRefusedByName) {
  test::TempDir dir;
  const std::string path = dir / "huge.obj";
  std::ofstream(path) << "v -1e20 -1e20 -5e20\nv 1e20 -1e20 -5e20\nv 0 1e20 -5e20\nf 1 2 3\n";
  try {
    loadScene(path);
    FAIL() << "accepted";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("huge.obj"), std::string::npos) << msg;
    EXPECT_NE(msg.find("overflow"), std::string::npos) << msg;
  }
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// recentre: a scene far from the origin moves next to it by a shift that leaves every vertex
// exact (origin + new position == old position, in double); a scene near the origin stays.
/// A Quake 3 map (IBSP 46) with a drawn texture and a nodraw one (surface flag 0x80), one polygon
/// triangle, an arch patch of 5 × 3 control points (two Bézier patches side by side: a half
/// cylinder of radius 1 around the y axis, y from 0 to 2, normals outward) and a nodraw 3 × 3
/// patch; the other lumps empty.
std::string mapWithPatches() {
  auto f32 = [](std::string& s, float v) {
    uint32_t bits;
    std::memcpy(&bits, &v, 4);
    test::appendLe32(s, bits);
  };
  std::string textures;
  for (const auto& [name, flags] : {std::pair{"t/wall", 0u}, std::pair{"t/caulk", 0x80u}}) {
    std::string t(name);
    t.resize(64, '\0');
    test::appendLe32(t, flags), test::appendLe32(t, 1);
    textures += t;
  }
  std::string vertices;
  auto vertex = [&](glm::vec3 p, glm::vec3 n) {
    std::string v;
    for (int a = 0; a < 3; ++a) f32(v, p[a]);
    v.resize(28, '\0');
    for (int a = 0; a < 3; ++a) f32(v, n[a]);
    v.resize(44, '\0');
    vertices += v;
  };
  for (glm::vec3 p : {glm::vec3(5, 0, 0), glm::vec3(6, 0, 0), glm::vec3(5, 1, 0)}) vertex(p, {0, 0, 1});
  const glm::vec2 arch[5] = {{1, 0}, {1, 1}, {0, 1}, {-1, 1}, {-1, 0}};  // (x, z)
  for (int row = 0; row < 3; ++row)
    for (const glm::vec2 c : arch) vertex({c.x, float(row), c.y}, glm::normalize(glm::vec3(c.x, 0.0f, c.y)));
  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 3; ++col) vertex({float(col), float(row), 3.0f}, {0, 0, 1});
  std::string meshVerts, faces;
  for (uint32_t v = 0; v < 3; ++v) test::appendLe32(meshVerts, v);
  auto face = [&](int texture, int type, int vertex0, int count, int meshCount, int w, int h) {
    std::string f;
    for (int32_t x : {texture, -1, type, vertex0, count, 0, meshCount, -1}) test::appendLe32(f, uint32_t(x));
    f.resize(96, '\0');
    test::appendLe32(f, uint32_t(w)), test::appendLe32(f, uint32_t(h));
    faces += f;
  };
  face(0, 1, 0, 3, 3, 0, 0);   // the polygon
  face(0, 2, 3, 15, 0, 5, 3);  // the arch
  face(1, 2, 18, 9, 0, 3, 3);  // the nodraw patch
  return test::quake3Map({{1, textures}, {10, vertices}, {11, meshVerts}, {13, faces}});
}

/// The arch's cross-section: two quadratic Béziers in (x, z), in double.
glm::dvec2 archAt(double s) {
  const glm::dvec2 p[5] = {{1, 0}, {1, 1}, {0, 1}, {-1, 1}, {-1, 0}};
  const int k = s < 0.5 ? 0 : 2;
  const double t = s < 0.5 ? 2 * s : 2 * s - 1;
  return (1 - t) * (1 - t) * p[k] + 2 * t * (1 - t) * p[k + 1] + t * t * p[k + 2];
}

/// Distance from (x, z) to the arch's cross-section (sampled finely).
double distanceToArch(glm::dvec2 q) {
  double best = 1e30;
  for (int i = 0; i <= 20000; ++i) best = std::min(best, glm::length(q - archAt(i / 20000.0)));
  return best;
}

// Quake 3 maps (docs/data.md): assimp 5.2's importer drops Quake 3's curved surfaces. They are
// tessellated from the map: on the Bézier surface, within the tolerance, one watertight grid across
// both patches, front faces toward the control points' normals; nodraw patches (collision only) are
// skipped.
TEST(SceneQuake3, PatchesAreTessellatedOnTheirSurfaceWithinTheTolerance) {
  const std::string map = mapWithPatches();
  const auto* bytes = reinterpret_cast<const unsigned char*>(map.data());
  size_t previous = 0;
  for (const float tolerance : {0.1f, 0.01f, 0.001f}) {
    SCOPED_TRACE(tolerance);
    const Quake3Patches p = tessellateQuake3Patches(bytes, map.size(), tolerance);
    ASSERT_EQ(p.keys, std::vector<std::string>{"0.-1"}) << "the nodraw patch (texture 1) is skipped";
    ASSERT_EQ(p.triKey.size(), p.triangles.size());
    EXPECT_GT(p.triangles.size(), previous) << "a smaller tolerance takes more triangles";
    previous = p.triangles.size();
    for (const glm::vec3& v : p.positions) {
      EXPECT_LT(distanceToArch({v.x, v.z}), 1e-4) << v.x << "," << v.y << "," << v.z;
      EXPECT_TRUE(v.y >= 0.0f && v.y <= 2.0f);
    }
    for (const glm::vec3 corner : {glm::vec3(1, 0, 0), glm::vec3(-1, 0, 0), glm::vec3(0, 0, 1)})  // the patches' corners at y = 0
      EXPECT_NE(std::find(p.positions.begin(), p.positions.end(), corner), p.positions.end()) << "control corners are exact";
    std::map<std::pair<uint32_t, uint32_t>, int> edges;
    for (const glm::uvec3& t : p.triangles) {
      const glm::vec3 a = p.positions[t.x], b = p.positions[t.y], c = p.positions[t.z], centroid = (a + b + c) / 3.0f;
      EXPECT_GT(glm::dot(glm::cross(b - a, c - a), glm::vec3(centroid.x, 0.0f, centroid.z)), 0.0f) << "front faces outward";
      EXPECT_LT(distanceToArch({centroid.x, centroid.z}), double(tolerance) + 1e-5);
      for (int e = 0; e < 3; ++e) ++edges[std::minmax(t[e], t[(e + 1) % 3])];
    }
    // Watertight: an edge used once lies on the grid's border (y = 0 or 2, or the arch's ends).
    for (const auto& [edge, uses] : edges) {
      ASSERT_LE(uses, 2);
      if (uses == 1) {
        const glm::vec3 a = p.positions[edge.first], b = p.positions[edge.second];
        const auto at = [](float v, float x) { return std::abs(v - x) < 1e-5f; };
        const bool border = (at(a.y, 0.0f) && at(b.y, 0.0f)) || (at(a.y, 2.0f) && at(b.y, 2.0f)) || (at(a.z, 0.0f) && at(b.z, 0.0f));
        EXPECT_TRUE(border) << "a crack between " << a.x << "," << a.y << "," << a.z << " and " << b.x << "," << b.y << "," << b.z;
      }
    }
  }
}

// Through the loader: a .pk3 holding the map gives assimp's polygon plus the patch, in the
// material assimp named for the same key, transformed with the model.
TEST(SceneQuake3, AnArchivesPatchesJoinTheImportersGeometry) {
  test::TempDir dir;
  const std::string map = mapWithPatches(), path = dir / "arch.pk3";
  std::ofstream(path, std::ios::binary) << test::storedZip("maps/arch.bsp", map);
  const Quake3Patches p = tessellateQuake3Patches(reinterpret_cast<const unsigned char*>(map.data()), map.size(), 1.0f);
  const glm::mat4 move = glm::translate(glm::mat4(1.0f), glm::vec3(10.0f, 0.0f, 0.0f));
  const Scene s = loadModel(path, move);
  ASSERT_EQ(s.triangleCount(), 1 + p.triangles.size());
  size_t onArch = 0;
  for (size_t t = 0; t < s.triangleCount(); ++t) {
    EXPECT_EQ(s.triMaterial[t], s.triMaterial[0]) << "one material for the polygon and the patch";
    EXPECT_EQ(s.materials[s.triMaterial[t]].name, "t/wall") << "named by the shader of the face's texture record";
    const glm::vec3 c = (s.positions[s.triangles[t].x] + s.positions[s.triangles[t].y] + s.positions[s.triangles[t].z]) / 3.0f;
    onArch += distanceToArch({c.x - 10.0f, c.z}) < 1.0 + 1e-4 && c.z >= 0.0f && c.x < 11.5f;
  }
  EXPECT_EQ(onArch, p.triangles.size());
  EXPECT_EQ(s.bounds().hi.x, 16.0f);  // the polygon, moved
  EXPECT_EQ(s.bounds().lo.x, 9.0f);   // the arch's end, moved
  // A mirroring transform keeps the patch's front faces outward, as it does the importer's.
  const Scene mirrored = loadModel(path, glm::scale(glm::mat4(1.0f), glm::vec3(-1.0f, 1.0f, 1.0f)));
  ASSERT_EQ(mirrored.triangleCount(), s.triangleCount());
  for (size_t t = 1; t < mirrored.triangleCount(); ++t) {  // the polygon comes first
    const glm::vec3 a = mirrored.positions[mirrored.triangles[t].x], b = mirrored.positions[mirrored.triangles[t].y],
                    c = mirrored.positions[mirrored.triangles[t].z], centroid = (a + b + c) / 3.0f;
    EXPECT_GT(glm::dot(glm::cross(b - a, c - a), glm::vec3(centroid.x, 0.0f, centroid.z)), 0.0f) << t;
  }
}

// A material's diffuse texture multiplies its colour; under --textures off (flattenTextures) the
// albedo is the texture's mean colour (averaged in linear space) times the material's colour. A
// texture that cannot be read leaves the material's colour, with one warning naming the file,
// and the model still loads.
TEST(SceneLoad, TexturedMaterialsTakeTheTexturesMeanColour) {
  test::TempDir dir;
  const uint8_t texels[] = {255, 0, 0, 0, 0, 255, 255, 255, 255, 0, 0, 0};  // red, blue, white, black
  writePngBytes(dir / "tex.png", 2, 2, 3, texels);
  std::ofstream(dir / "m.mtl") << "newmtl white\nKd 1 1 1\nmap_Kd tex.png\n"
                                  "newmtl grey\nKd 0.5 0.5 0.5\nmap_Kd tex.png\n"
                                  "newmtl lost\nKd 1 1 1\nmap_Kd missing.png\n";
  std::ofstream(dir / "m.obj") << "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n"
                                  "usemtl white\nf 1/1 2/2 3/3\nusemtl grey\nf 2/2 4/4 3/3\nusemtl lost\nf 1/1 3/3 4/4\n";
  std::vector<std::string> warnings;
  const WarningSink previous = setWarningSink([&](const std::string& w) { warnings.push_back(w); });
  Scene s = loadModel(dir / "m.obj");
  setWarningSink(previous);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("missing.png"), std::string::npos) << warnings[0];
  std::map<std::string, Material> byName;
  for (const Material& m : s.materials) byName[m.name] = m;
  ASSERT_EQ(s.textures.size(), 1u) << "decoded once for both materials";
  EXPECT_EQ(byName["white"].baseTexture, 0);
  EXPECT_EQ(byName["grey"].baseTexture, 0);
  EXPECT_EQ(byName["lost"].baseTexture, -1);
  EXPECT_EQ(byName["lost"].albedo, glm::vec3(1.0f)) << "an unreadable texture: the material's colour";
  EXPECT_EQ(s.texcoords.size(), s.positions.size());
  flattenTextures(s);
  std::map<std::string, glm::vec3> albedo;
  for (const Material& m : s.materials) albedo[m.name] = m.albedo;
  const glm::vec3 mean(0.5f, 0.25f, 0.5f);  // (1 + 0 + 1 + 0) / 4 red, (0 + 0 + 1 + 0) / 4 green, …
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(albedo["white"][c], mean[c], 1e-6f) << c;
    EXPECT_NEAR(albedo["grey"][c], 0.5f * mean[c], 1e-6f) << c;
  }
  // A truncated image does not decode (decodeRgba8; the loader then warns).
  const std::string png = [&] {
    std::ifstream in(dir / "tex.png", std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }();
  const auto* bytes = reinterpret_cast<const uint8_t*>(png.data());
  EXPECT_TRUE(decodeRgba8(bytes, png.size(), "tex.png").has_value());
  EXPECT_FALSE(decodeRgba8(bytes, png.size() / 2, "tex.png").has_value());
}

std::string base64(const std::string& bytes) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const size_t n = std::min<size_t>(3, bytes.size() - i);
    uint32_t v = 0;
    for (size_t k = 0; k < 3; ++k) v = v << 8 | (k < n ? uint32_t(uint8_t(bytes[i + k])) : 0u);
    for (size_t k = 0; k < 4; ++k) out += k <= n ? digits[(v >> (18 - 6 * k)) & 63] : '=';
  }
  return out;
}

// The same for a texture embedded in the model (a glTF image as a data URI, assimp's "*0"), times
// the material's base colour factor; a mesh without texture coordinates gets the mean colour
// without being asked.
TEST(SceneLoad, EmbeddedTexturesGiveTheirMeanColourToo) {
  test::TempDir dir;
  const uint8_t texels[] = {255, 0, 0, 0, 0, 255, 255, 255, 255, 0, 0, 0};
  writePngBytes(dir / "tex.png", 2, 2, 3, texels);
  std::ifstream in(dir / "tex.png", std::ios::binary);
  const std::string png((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string positions;
  for (float v : {0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f}) positions.append(reinterpret_cast<const char*>(&v), 4);
  std::ofstream(dir / "t.gltf") << R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
    "materials": [{"name": "tex", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "baseColorFactor": [1, 0.5, 1, 1]}}],
    "textures": [{"source": 0}], "images": [{"uri": "data:image/png;base64,)" + base64(png) + R"("}],
    "buffers": [{"byteLength": 36, "uri": "data:application/octet-stream;base64,)" + base64(positions) + R"("}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}]})";
  const Scene s = loadModel(dir / "t.gltf");  // no texture coordinates: the texture's mean colour
  const auto m = std::find_if(s.materials.begin(), s.materials.end(), [](const Material& x) { return x.name == "tex"; });
  ASSERT_NE(m, s.materials.end());
  EXPECT_NEAR(m->albedo.x, 0.5f, 1e-6f);
  EXPECT_NEAR(m->albedo.y, 0.125f, 1e-6f);
  EXPECT_NEAR(m->albedo.z, 0.5f, 1e-6f);
}

/// A one-triangle glTF whose material's base colour texture is `png` (embedded), with `material`
/// spliced into the material's JSON (alphaMode and alphaCutoff) and texture coordinates.
std::string texturedGltf(const std::string& png, const std::string& material) {
  std::string data;
  for (float v : {0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f})
    data.append(reinterpret_cast<const char*>(&v), 4);
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
    "materials": [{"name": "tex", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}})" + material + R"(}],
    "textures": [{"source": 0, "sampler": 0}], "samplers": [{"wrapS": 33071, "wrapT": 33648}],
    "images": [{"uri": "data:image/png;base64,)" + base64(png) + R"("}],
    "buffers": [{"byteLength": 60, "uri": "data:application/octet-stream;base64,)" + base64(data) + R"("}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 24}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                  {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}]})";
}

std::string pngOf(const test::TempDir& dir, int w, int h, int channels, const std::vector<uint8_t>& px) {
  writePngBytes(dir / "img.png", w, h, channels, px.data());
  std::ifstream in(dir / "img.png", std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Alpha tests as glTF asks for them: MASK with its cut-off; OPAQUE (the default) and BLEND
// ignore alpha. (Formats without an alpha mode cut out 1-bit alpha: CliTextures.)
// The sampler's wrap modes (CLAMP_TO_EDGE, MIRRORED_REPEAT) reach the material.
TEST(SceneLoad, GltfAlphaModesAndWrapModes) {
  test::TempDir dir;
  const std::string binary = pngOf(dir, 2, 1, 4, {255, 0, 0, 255, 0, 255, 0, 0});
  const std::string partial = pngOf(dir, 2, 1, 4, {255, 0, 0, 255, 0, 255, 0, 100});
  auto cutoff = [&](const std::string& png, const std::string& material) {
    std::ofstream(dir / "a.gltf") << texturedGltf(png, material);
    const Scene s = loadModel(dir / "a.gltf");
    const auto m = std::find_if(s.materials.begin(), s.materials.end(), [](const Material& x) { return x.name == "tex"; });
    EXPECT_NE(m, s.materials.end());
    EXPECT_GE(m->baseTexture, 0);
    EXPECT_EQ(m->wrapU, TextureWrap::Clamp);
    EXPECT_EQ(m->wrapV, TextureWrap::Mirror);
    EXPECT_EQ(s.texcoords.size(), s.positions.size());
    return m->alphaCutoff;
  };
  EXPECT_FLOAT_EQ(cutoff(partial, R"(, "alphaMode": "MASK", "alphaCutoff": 0.3)"), 0.3f);
  EXPECT_FLOAT_EQ(cutoff(partial, R"(, "alphaMode": "MASK")"), 0.5f);
  EXPECT_LT(cutoff(binary, R"(, "alphaMode": "OPAQUE")"), 0.0f);
  EXPECT_LT(cutoff(binary, ""), 0.0f) << "glTF's default alpha mode is OPAQUE";
  EXPECT_LT(cutoff(partial, R"(, "alphaMode": "BLEND")"), 0.0f) << "blending is drawn opaque";
}

// A texture over 16384 pixels a side is refused with one line naming it; one that does not
// decode leaves the material untextured with a warning, and the model loads.
TEST(SceneLoad, OversizedTexturesAreRefusedAndUndecodableOnesWarn) {
  test::TempDir dir;
  const std::string wide = pngOf(dir, 16385, 1, 3, std::vector<uint8_t>(16385 * 3, 7));
  std::ofstream(dir / "wide.gltf") << texturedGltf(wide, "");
  try {
    loadModel(dir / "wide.gltf");
    ADD_FAILURE() << "a 16385-pixel-wide texture loaded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("16385"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line";
  }
  std::ofstream(dir / "bad.png") << "not an image at all";
  std::ofstream(dir / "m.mtl") << "newmtl m\nKd 0.3 0.4 0.5\nmap_Kd bad.png\n";
  std::ofstream(dir / "m.obj") << "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl m\nf 1/1 2/1 3/1\n";
  std::vector<std::string> warnings;
  const WarningSink previous = setWarningSink([&](const std::string& w) { warnings.push_back(w); });
  const Scene s = loadModel(dir / "m.obj");
  setWarningSink(previous);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("bad.png"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("does not decode"), std::string::npos) << warnings[0];
  EXPECT_EQ(s.materials[s.triMaterial[0]].baseTexture, -1);
  EXPECT_NEAR(s.materials[s.triMaterial[0]].albedo.y, 0.4f, 1e-6f);
}

// A 3MF file with a thumbnail, as most 3MF writers make them: assimp 5.2.5's importer leaves the
// scene's texture pointers dangling and its destructor frees them again (found by a sweep of
// assimp's models: "free(): invalid pointer", status 134, on assimp's own cube_gears_prod_req.3mf;
// under ASan a double free). It loads now, from a file and from memory, with its one triangle.
TEST(SceneLoad, A3mfWithAThumbnailLoads) {
  test::TempDir dir;
  const uint8_t texel[] = {0, 255, 0};
  writePngBytes(dir / "thumbnail.png", 1, 1, 3, texel);
  std::ifstream in(dir / "thumbnail.png", std::ios::binary);
  const std::string png((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string types = R"(<?xml version="1.0" encoding="utf-8"?>
<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">
<Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>
<Default Extension="png" ContentType="image/png"/>
<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/></Types>)";
  const std::string rels = R"(<?xml version="1.0" encoding="utf-8"?>
<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">
<Relationship Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel" Target="/3D/3dmodel.model" Id="rel0"/>
<Relationship Type="http://schemas.openxmlformats.org/package/2006/relationships/metadata/thumbnail" Target="/Metadata/thumbnail.png" Id="rel1"/>
</Relationships>)";
  const std::string model = R"(<?xml version="1.0" encoding="utf-8"?>
<model xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02" unit="millimeter"><resources>
<object id="1" type="model"><mesh><vertices><vertex x="0" y="0" z="0"/><vertex x="1" y="0" z="0"/><vertex x="0" y="1" z="0"/></vertices>
<triangles><triangle v1="0" v2="1" v3="2"/></triangles></mesh></object></resources><build><item objectid="1"/></build></model>)";
  const std::string zip = test::storedZip(
      {{"[Content_Types].xml", types}, {"_rels/.rels", rels}, {"3D/3dmodel.model", model}, {"Metadata/thumbnail.png", png}});
  std::ofstream(dir / "thumb.3mf", std::ios::binary) << zip;
  const Scene fromFile = loadModel(dir / "thumb.3mf");
  EXPECT_EQ(fromFile.triangles.size(), 1u);
  const Scene fromMemory = loadModelFromMemory(zip.data(), zip.size(), "3mf", "thumb.3mf");
  EXPECT_EQ(fromMemory.triangles.size(), 1u);
}

// Material strings are read from the property's bytes: assimp's getter aborts the process on a
// string stored without its zero byte (assimp 5.2.5's MDL7 reader writes such texture names:
// found by a sweep of assimp's models, `broadleavedtreeD.mdl`, status 134), and trusts the stored
// length. Its number getters parse strings and abort on the same, so such a number is not read.
TEST(SceneLoad, MaterialStringsWithoutTheirZeroByteAreRead) {
  aiMaterial m;
  aiString name("brick");
  m.AddProperty(&name, AI_MATKEY_NAME);
  EXPECT_EQ(materialString(&m, AI_MATKEY_NAME), "brick");
  EXPECT_FALSE(materialString(&m, AI_MATKEY_TEXTURE_DIFFUSE(0)));
  auto raw = [](uint32_t length, const std::string& bytes) {
    std::string data(4, '\0');
    std::memcpy(data.data(), &length, 4);
    return data + bytes;
  };
  const std::string unterminated = raw(8, "wall.tga");  // no zero byte after the name
  m.AddBinaryProperty(unterminated.data(), unsigned(unterminated.size()), AI_MATKEY_TEXTURE_DIFFUSE(0), aiPTI_String);
  EXPECT_EQ(materialString(&m, AI_MATKEY_TEXTURE_DIFFUSE(0)), "wall.tga");
  const std::string overlong = raw(1000, "roof.png");  // declares more bytes than it holds
  m.AddBinaryProperty(overlong.data(), unsigned(overlong.size()), AI_MATKEY_TEXTURE(aiTextureType_BASE_COLOR, 0), aiPTI_String);
  EXPECT_EQ(materialString(&m, AI_MATKEY_TEXTURE(aiTextureType_BASE_COLOR, 0)), "roof.png");
  const std::string stops = raw(9, std::string("a.png\0xyz", 9));  // ends at the first zero byte
  m.AddBinaryProperty(stops.data(), unsigned(stops.size()), AI_MATKEY_TEXTURE_NORMALS(0), aiPTI_String);
  EXPECT_EQ(materialString(&m, AI_MATKEY_TEXTURE_NORMALS(0)), "a.png");
  const std::string tooShort = "ab";  // not even a length
  m.AddBinaryProperty(tooShort.data(), unsigned(tooShort.size()), AI_MATKEY_TEXTURE_SPECULAR(0), aiPTI_String);
  EXPECT_FALSE(materialString(&m, AI_MATKEY_TEXTURE_SPECULAR(0)));
  const float notAString = 2.0f;
  m.AddProperty(&notAString, 1, AI_MATKEY_TEXTURE_EMISSIVE(0));
  EXPECT_FALSE(materialString(&m, AI_MATKEY_TEXTURE_EMISSIVE(0)));
  // Numbers: assimp parses a number stored as a string — it aborts on one without its zero byte,
  // fails on one number and throws on several — so such a property is not read.
  EXPECT_FALSE(readableNumber(&m, AI_MATKEY_COLOR_DIFFUSE));
  const aiColor3D red(1, 0, 0);
  m.AddProperty(&red, 1, AI_MATKEY_COLOR_DIFFUSE);
  EXPECT_TRUE(readableNumber(&m, AI_MATKEY_COLOR_DIFFUSE));
  const std::string number = raw(3, std::string("0.5\0", 4));
  m.AddBinaryProperty(number.data(), unsigned(number.size()), AI_MATKEY_SHININESS, aiPTI_String);
  float shininess = 0.0f;
  EXPECT_NE(m.Get(AI_MATKEY_SHININESS, shininess), AI_SUCCESS);
  EXPECT_FALSE(readableNumber(&m, AI_MATKEY_SHININESS));
  const std::string colour = raw(11, std::string("0.5 0.5 0.5\0", 12));
  m.AddBinaryProperty(colour.data(), unsigned(colour.size()), AI_MATKEY_COLOR_SPECULAR, aiPTI_String);
  aiColor3D specular;
  EXPECT_ANY_THROW(m.Get(AI_MATKEY_COLOR_SPECULAR, specular));
  EXPECT_FALSE(readableNumber(&m, AI_MATKEY_COLOR_SPECULAR));
  const std::string cut = raw(3, "0.5");  // no zero byte: assimp's getter would abort
  m.AddBinaryProperty(cut.data(), unsigned(cut.size()), AI_MATKEY_OPACITY, aiPTI_String);
  EXPECT_FALSE(readableNumber(&m, AI_MATKEY_OPACITY));
}

TEST(SceneRecentre, MovesOnlyFarScenesAndKeepsEveryVertexExact) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (const glm::vec3 centre : {glm::vec3(0.0f), glm::vec3(3.0f, -2.0f, 1.0f), glm::vec3(1e5f, 3.0f, -2.5e5f), glm::vec3(-7e6f, 6e6f, 1e7f),
                                 glm::vec3(20.0f, 0.0f, 0.0f)}) {
    SCOPED_TRACE(centre.x);
    Scene s = makeSphere(centre, 2.0f, 24);
    for (glm::vec3& p : s.positions) p += glm::vec3(u(rng), u(rng), u(rng)) * 0.01f;  // not on a nice grid
    s.lights.push_back({centre + glm::vec3(0.0f, 3.0f, 0.0f), glm::vec3(1.0f)});
    const Scene before = s;
    recentre(s);
    const bool far = glm::length(centre) > 100.0f;
    EXPECT_EQ(s.origin != glm::dvec3(0.0), far);
    for (size_t i = 0; i < s.positions.size(); ++i) ASSERT_EQ(s.toWorld(s.positions[i]), glm::dvec3(before.positions[i])) << i;
    EXPECT_EQ(s.toWorld(s.lights[0].position), glm::dvec3(before.lights[0].position));
    EXPECT_LE(glm::length(s.bounds().center()), 8.0f * s.bounds().diagonal());
    if (far) {
      EXPECT_LE(glm::length(s.bounds().center()), s.bounds().diagonal());
    }
  }
}

}  // namespace
}  // namespace lt
