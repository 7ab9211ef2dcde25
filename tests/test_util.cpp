#include "layertrace/pipeline/gpu_tracers.h"
#include "test_util.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <glm/geometric.hpp>

#include "layertrace/util/image.h"

#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

namespace lt::test {

std::shared_ptr<GpuContext> GpuSuite::gpu_;

void GpuSuite::SetUpTestSuite() {
  if (std::getenv("LAYERTRACE_SANITIZED")) return;
  gpu_ = openGpu();
}

void GpuSuite::TearDownTestSuite() { gpu_.reset(); }

void GpuSuite::SetUp() {
  if (!gpu_) GTEST_SKIP() << "sanitized build: the GPU driver is not instrumented";
}
namespace fs = std::filesystem;

TempDir::TempDir() {
  static int counter = 0;
  path = fs::temp_directory_path() / ("layertrace_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  fs::remove_all(path);
  fs::create_directories(path);
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path, ec);
}

int runCli(const std::string& args, std::string* err, std::string* out) {
  TempDir tmp;
  const std::string cmd = std::string(LAYERTRACE_CLI) + " " + args + " >" + (tmp / "out") + " 2>" + (tmp / "err");
  const int status = std::system(cmd.c_str());
  auto slurp = [](const std::string& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  if (err) *err = slurp(tmp / "err");
  if (out) *out = slurp(tmp / "out");
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

FrameOptions realSceneOptions(const std::string& sceneFile, const std::string& camera) {
  FrameOptions o;
  o.scenePath = sourceDir() + "/scenes/" + sceneFile;
  o.cameraName = camera;
  return o;
}

FrameOptions defaultSceneOptions(int W, int H) {
  FrameOptions o;
  o.scenePath = sourceDir() + "/scenes/default.json";
  o.width = W, o.height = H;
  return o;
}

void writeTriangleWithCamera(const std::string& path) {
  std::ofstream(path) << R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
    "nodes": [{"mesh": 0}, {"camera": 0, "name": "modelcam", "translation": [0, 0, 10]}],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "aspectRatio": 1.5, "znear": 0.1, "zfar": 100}}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}],
    "bufferViews": [{"buffer": 0, "byteLength": 36}],
    "buffers": [{"byteLength": 36, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}]})";
}

bool haveFetchedScenes() { return fs::exists(sourceDir() + "/data/models/AC14-FZK-Haus.ifc"); }

CameraDesc originCamera(float fovY, float near, float far) {
  CameraDesc d;
  d.name = "origin";
  d.eye = {0, 0, 0};
  d.target = {0, 0, -1};
  d.up = {0, 1, 0};
  d.fovY = fovY;
  d.near = near;
  d.far = far;
  return d;
}

void addTriangle(Scene& s, glm::vec3 a, glm::vec3 b, glm::vec3 c, uint32_t material) {
  const auto base = uint32_t(s.positions.size());
  s.positions.insert(s.positions.end(), {a, b, c});
  s.normals.insert(s.normals.end(), 3, glm::vec3(0.0f));
  s.triangles.push_back({base, base + 1, base + 2});
  s.triMaterial.push_back(material);
  if (s.materials.empty()) s.materials.push_back(Material{"default"});
}

std::string sceneCaseName(const std::string& sceneFile) {
  std::string n = sceneFile.substr(0, sceneFile.find('.'));
  std::replace(n.begin(), n.end(), '-', '_');
  return n;
}

std::vector<Ray> sampleRays(const Frame& f, size_t count, uint64_t seed, bool screenLines) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> px(0, f.camera.width() - 1), py(0, f.camera.height() - 1);
  std::normal_distribution<float> g;
  std::vector<Ray> rays;
  const float maxDist = f.scene.bounds().diagonal();
  while (rays.size() < count) {
    const int x = px(rng), y = py(rng);
    if (f.layers.countAt(x, y) == 0) continue;
    const FragmentNode& frag = f.layers.pixel(x, y)[0];
    Ray r;
    r.origin = f.camera.rayThrough({x + 0.5f, y + 0.5f}) * frag.depth;
    const glm::vec3 n = decodeOctahedral(frag.normal);
    const glm::vec3 v = glm::normalize(r.origin);
    if (screenLines && rays.size() % 4 == 3) {
      // Exactly diagonal or axis-parallel screen lines through pixel corners (the DDA's ties):
      // a direction parallel to the image plane projects to a line of the same direction.
      static const glm::vec3 dirs[8] = {{1, 1, 0}, {1, -1, 0}, {-1, 1, 0}, {-1, -1, 0}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}};
      r.dir = glm::normalize(dirs[rays.size() / 4 % 8]);
    } else if (rays.size() % 2 == 0) {
      r.dir = glm::reflect(v, glm::dot(n, v) > 0.0f ? -n : n);
    } else {
      r.dir = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
    }
    r.maxDistance = maxDist;
    rays.push_back(r);
  }
  return rays;
}

/// A frame of an in-code scene: rasterized and sorted with the given view, size, k, thickness.
Frame frameOf(const Scene& scene, const CameraDesc& view, int W, int H, int k, float thickness) {
  Frame f;
  f.scene = scene;
  f.camera = Camera(view, W, H);
  f.thickness = thickness;
  FrameOptions o;
  o.width = W, o.height = H, o.layers = k, o.thickness = thickness;
  rasterizeFrame(o, f);
  return f;
}

::testing::AssertionResult sameListContents(const FragmentLists& a, const FragmentLists& b) {
  if (a.head.size() != b.head.size()) return ::testing::AssertionFailure() << "pixel counts differ";
  for (size_t p = 0; p < a.head.size(); ++p)
    for (uint32_t i = a.head[p], j = b.head[p];; i = a.nodes[i].next, j = b.nodes[j].next) {
      if (i == kNullIndex || j == kNullIndex) {
        if (i != j) return ::testing::AssertionFailure() << "pixel " << p << ": lists of different lengths";
        break;
      }
      const FragmentNode &x = a.nodes[i], &y = b.nodes[j];
      if (x.depth != y.depth || x.normal != y.normal || x.albedoSpec != y.albedoSpec || a.triangle[i] != b.triangle[j])
        return ::testing::AssertionFailure() << "pixel " << p << ": fragments differ (depth " << x.depth << " vs " << y.depth << ")";
    }
  return ::testing::AssertionSuccess();
}

uint64_t testSeed() {
  const char* env = std::getenv("LAYERTRACE_TEST_SEED");
  return env ? std::strtoull(env, nullptr, 10) : 20171122ull;
}

Ray freeRay(glm::vec3 origin, glm::vec3 dir, float maxDistance) {
  Ray r;
  r.origin = origin;
  r.dir = glm::normalize(dir);
  r.maxDistance = maxDistance;
  r.startsOnSurface = false;
  return r;
}

void appendLe32(std::string& s, uint32_t v) {
  for (int i = 0; i < 4; ++i) s += char((v >> (8 * i)) & 0xFF);
}

std::string quake3Map(const std::map<int, std::string>& lumps) {
  std::string map = "IBSP", body;
  appendLe32(map, 46);
  const uint32_t start = 8 + 8 * 17;
  for (int l = 0; l < 17; ++l) {
    const auto it = lumps.find(l);
    const std::string& data = it == lumps.end() ? std::string() : it->second;
    appendLe32(map, start + uint32_t(body.size())), appendLe32(map, uint32_t(data.size()));
    body += data;
  }
  return map + body;
}

std::string storedZip(const std::string& name, const std::string& data, std::optional<uint32_t> declared) {
  return storedZip({{name, data}}, declared);
}

std::string storedZip(const std::vector<std::pair<std::string, std::string>>& entries, std::optional<uint32_t> declared) {
  auto u16 = [](std::string& s, uint16_t v) { s += char(v & 0xFF), s += char(v >> 8); };
  std::string z, directory;
  for (const auto& [name, data] : entries) {
    const auto crc = uint32_t(crc32(0, reinterpret_cast<const Bytef*>(data.data()), uInt(data.size())));
    const auto packed = uint32_t(data.size()), unpacked = declared.value_or(packed), local = uint32_t(z.size());
    appendLe32(z, 0x04034b50), u16(z, 20), u16(z, 0), u16(z, 0), u16(z, 0), u16(z, 0);
    appendLe32(z, crc), appendLe32(z, packed), appendLe32(z, unpacked), u16(z, uint16_t(name.size())), u16(z, 0);
    z += name + data;
    appendLe32(directory, 0x02014b50), u16(directory, 20), u16(directory, 20), u16(directory, 0), u16(directory, 0), u16(directory, 0);
    u16(directory, 0), appendLe32(directory, crc), appendLe32(directory, packed), appendLe32(directory, unpacked);
    u16(directory, uint16_t(name.size())), u16(directory, 0), u16(directory, 0), u16(directory, 0), u16(directory, 0);
    appendLe32(directory, 0), appendLe32(directory, local);
    directory += name;
  }
  const auto start = uint32_t(z.size());
  const auto count = uint16_t(entries.size());
  z += directory;
  appendLe32(z, 0x06054b50), u16(z, 0), u16(z, 0), u16(z, count), u16(z, count), appendLe32(z, uint32_t(directory.size()));
  appendLe32(z, start), u16(z, 0);
  return z;
}

std::string writeGrateObj(const TempDir& dir, int side) {
  const int w = side, h = side > 16384 ? 1 : side;
  std::vector<uint8_t> px(size_t(w) * size_t(h) * 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* p = &px[(size_t(y) * size_t(w) + size_t(x)) * 4];
      p[0] = uint8_t(16 * (x % 16)), p[1] = uint8_t(16 * (y % 16)), p[2] = 180;
      p[3] = side > 16384 || (x / 2 + y / 2) % 2 ? 255 : 0;  // 2 × 2-texel checks
    }
  writePngBytes(dir / "grate.png", w, h, 4, px.data());
  std::ofstream(dir / "grate.mtl") << "newmtl wall\nKd 0.3 0.6 0.4\nnewmtl grate\nKd 1 1 1\nmap_Kd grate.png\n";
  std::ofstream(dir / "grate.obj") << "mtllib grate.mtl\n"
                                      "v -3 -2 -4\nv 3 -2 -4\nv 3 3 -4\nv -3 3 -4\nv -3 -1 0\nv 3 -1 0\nv 3 -1 -3.9\nv -3 -1 -3.9\n"
                                      "v -1.3 -0.9 -2.1\nv 1.2 -0.8 -1.9\nv 1.25 1.6 -2.0\nv -1.2 1.55 -2.05\n"
                                      "vt 0 0\nvt 2 0\nvt 2 2\nvt 0 2\n"
                                      "usemtl wall\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 5/1 6/2 7/3\nf 5/1 7/3 8/4\n"
                                      "usemtl grate\nf 9/1 10/2 11/3\nf 9/1 11/3 12/4\n";
  return dir / "grate.obj";
}

/// An inward-facing box [x0, x1] × [y0, y1] × [z1, z0] (z0 > z1), two triangles per wall, with
/// the smooth-box vertex normals, and a panel inside to be reflected.
Scene smoothRoom() {
  const glm::vec3 lo{-0.4f, -1.5f, -9.5f}, hi{9.6f, 1.5f, 0.5f};
  Scene s;
  auto corner = [&](int cx, int cy, int cz) { return glm::vec3(cx ? hi.x : lo.x, cy ? hi.y : lo.y, cz ? hi.z : lo.z); };
  auto normal = [](int cx, int cy, int cz) { return glm::normalize(glm::vec3(cx ? -1.0f : 1.0f, cy ? -1.0f : 1.0f, cz ? -1.0f : 1.0f)); };
  // Each wall: four corners in order, the triangles (0, 1, 2) and (0, 2, 3) facing inward.
  const int walls[6][4][3] = {{{0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0}}, {{0, 1, 0}, {1, 1, 0}, {1, 1, 1}, {0, 1, 1}},
                              {{0, 0, 0}, {0, 1, 0}, {0, 1, 1}, {0, 0, 1}}, {{1, 0, 0}, {1, 0, 1}, {1, 1, 1}, {1, 1, 0}},
                              {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {{0, 0, 1}, {0, 1, 1}, {1, 1, 1}, {1, 0, 1}}};
  for (const auto& w : walls) {
    for (const auto& [a, b, c] : {std::array{0, 1, 2}, std::array{0, 2, 3}}) {
      addTriangle(s, corner(w[a][0], w[a][1], w[a][2]), corner(w[b][0], w[b][1], w[b][2]), corner(w[c][0], w[c][1], w[c][2]));
      const size_t n = s.normals.size();  // (the triangle's three vertices are the last three)
      s.normals[n - 3] = normal(w[a][0], w[a][1], w[a][2]);
      s.normals[n - 2] = normal(w[b][0], w[b][1], w[b][2]);
      s.normals[n - 1] = normal(w[c][0], w[c][1], w[c][2]);
    }
  }
  s.materials[0].mirror = 1.0f;
  addTriangle(s, {3, -1, -6}, {5, -1, -6}, {5, 1, -6});
  addTriangle(s, {3, -1, -6}, {5, 1, -6}, {3, 1, -6});
  s.finalize("smooth-room");
  return s;
}

}  // namespace lt::test
