#include "test_util.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <sys/wait.h>
#include <unistd.h>

namespace lt::test {
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

uint64_t testSeed() {
  const char* env = std::getenv("LAYERTRACE_TEST_SEED");
  return env ? std::strtoull(env, nullptr, 10) : 20171122ull;
}

}  // namespace lt::test
