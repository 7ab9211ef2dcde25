// Helpers shared by the tests: small scenes built in code, temporary folders, the CLI runner.
#pragma once

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/trace/tracer.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"
#include "layertrace/util/simd_targets.h"

namespace lt {
class GpuContext;
}

namespace lt::test {

/// Whether the tests run under a sanitizer (LAYERTRACE_SANITIZED, set by `make test` for the ASan
/// and TSan suites, 5–15× slower). The heaviest tests then run a smaller workload of the same
/// kind: the sanitizers look for memory and thread errors, which the first rays and tiles
/// already exercise, not for rare rays, which the Release suite's full workloads look for.
inline bool sanitized() { return std::getenv("LAYERTRACE_SANITIZED") != nullptr; }
/// Whether this is the ThreadSanitizer build (CMake's LAYERTRACE_TSAN; GCC and Clang name it
/// differently).
#if defined(__SANITIZE_THREAD__)
inline constexpr bool kThreadSanitized = true;
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
inline constexpr bool kThreadSanitized = true;
#else
inline constexpr bool kThreadSanitized = false;
#endif
#else
inline constexpr bool kThreadSanitized = false;
#endif
/// A test whose rays run on the calling thread only skips itself under ThreadSanitizer: there is
/// no second thread for it to watch, and it runs 10× slower there. AddressSanitizer still runs it.
#define LT_SKIP_SINGLE_THREADED_UNDER_TSAN() \
  if (::lt::test::kThreadSanitized) GTEST_SKIP() << "one thread only: nothing for ThreadSanitizer to check"
/// `n` in the Release suite, a quarter of it (at least 1) under the sanitizers.
inline size_t sanitizedCount(size_t n) { return sanitized() ? std::max<size_t>(n / 4, 1) : n; }

/// A suite on the GPU: one context (pipeline/gpu_tracers.h openGpu) for the whole suite. Skipped
/// in the sanitized builds: Mesa's driver is not built with the sanitizers, and its threads and
/// allocations would be reported as ours (the sanitized suites test the CPU path).
class GpuSuite : public ::testing::Test {
 protected:
  static void SetUpTestSuite();
  static void TearDownTestSuite();
  void SetUp() override;
  static std::shared_ptr<GpuContext> gpu_;
};

/// A fresh, empty folder under the system temp dir, removed at destruction.
struct TempDir {
  std::filesystem::path path;
  TempDir();
  ~TempDir();
  std::string operator/(const std::string& name) const { return (path / name).string(); }
};

/// Runs the layertrace CLI with `args`; returns the exit status, stderr in `err`.
int runCli(const std::string& args, std::string* err = nullptr, std::string* out = nullptr);

/// The repository's source directory (for scenes/).
inline std::string sourceDir() { return LAYERTRACE_SOURCE_DIR; }

/// Runs `body` once on every vector target this build has and this CPU runs (util/simd_targets.h),
/// the lane loops restricted to that target, each failure naming it. Sanitized builds run the best
/// and the last (the scalar emulation, whose C++ the sanitizers see into) and leave the ones
/// between to the Release tests; so does `all = false` (for tests whose other runs cover the rest).
template <class Body>
void forEachSimdTarget(Body&& body, bool all = true) {
  std::vector<SimdTarget> targets = simdTargets();
  if ((!all || std::getenv("LAYERTRACE_SANITIZED")) && targets.size() > 2) targets = {targets.front(), targets.back()};
  for (const SimdTarget& t : targets) {
    SCOPED_TRACE("vector target " + t.name);
    const ScopedSimdTarget only(t);
    body(t);
  }
}

/// Frame options for a scene file of scenes/ (a fetched real scene) with one of its cameras.
FrameOptions realSceneOptions(const std::string& sceneFile, const std::string& camera);
/// The embedded default scene (scenes/default.json) at W × H, its first camera.
FrameOptions defaultSceneOptions(int W, int H);

/// Writes a glTF 2.0 model to `path`: one triangle (0,0,0) (1,0,0) (0,1,0) and a camera node
/// named "modelcam" at (0, 0, 10) looking down −z.
void writeTriangleWithCamera(const std::string& path);

/// An OBJ scene of a wall, a floor (sharing no edge with it) and, in front of the wall, a grate
/// mapped with a checkerboard PNG whose alpha is 1-bit (so a cut-out at 0.5): `dir`/grate.obj.
/// With `side` > 16384 the texture is that wide instead (one row, opaque), which the loader must
/// refuse. Views: the eye near (0.35, 0.45, 1.5) looking at (0, 0.2, -3).
std::string writeGrateObj(const TempDir& dir, int side = 16);

/// True when the fetched scenes are present (scripts/fetch-scenes.sh).
bool haveFetchedScenes();

/// A camera at the origin looking down -z (camera space = world space).
CameraDesc originCamera(float fovY = 60.0f, float near = 0.01f, float far = 100.0f);

/// A ray from free space (not from a stored surface: Ray::startsOnSurface = false), `dir` normalised.
Ray freeRay(glm::vec3 origin, glm::vec3 dir, float maxDistance = 1e30f);

/// Adds a triangle to a scene with one material.
void addTriangle(Scene& s, glm::vec3 a, glm::vec3 b, glm::vec3 c, uint32_t material = 0);

/// gtest parameter name of a real-scene case: "fzk-haus.json" → "fzk_haus".
std::string sceneCaseName(const std::string& sceneFile);

/// `count` rays from random covered pixels' front surfaces: mirror reflections, random
/// directions, and (with `screenLines`) exactly diagonal or axis-parallel screen lines
/// (the ties of the DDA), in turn.
std::vector<Ray> sampleRays(const Frame& f, size_t count, uint64_t seed, bool screenLines = true);

/// A frame of an in-code scene: rasterized and sorted with the given view, size, k, thickness.
Frame frameOf(const Scene& scene, const CameraDesc& view, int W, int H, int k = 4, float thickness = 0.1f);

/// Every pixel's list holds the same fragments (depth, normal, albedo, triangle) in the same
/// order in both, wherever in their storage the nodes lie.
::testing::AssertionResult sameListContents(const FragmentLists& a, const FragmentLists& b);

/// A Quake 3 map (IBSP 46) whose lumps hold the given bytes (lump number → records); the
/// other lumps are empty.
std::string quake3Map(const std::map<int, std::string>& lumps);

/// A zip archive with one stored entry `name` holding `data`; its headers declare `declared`
/// bytes uncompressed (default: the real size).
std::string storedZip(const std::string& name, const std::string& data, std::optional<uint32_t> declared = {});
/// The same with several stored entries (name, data), in this order.
std::string storedZip(const std::vector<std::pair<std::string, std::string>>& entries, std::optional<uint32_t> declared = {});

/// Appends `v` to `s` as 4 little-endian bytes (Quake 3 maps and zip headers).
void appendLe32(std::string& s, uint32_t v);

/// An inward-facing box room, two triangles per wall, whose vertex normals are averaged over the
/// three walls at each corner (every wall's shading normal tilts away from its plane toward the
/// edges), mirror walls, and a panel inside to be reflected: secondary rays along big flat faces.
Scene smoothRoom();

/// Seed for randomized tests: LAYERTRACE_TEST_SEED or a fixed default; printed on failure.
uint64_t testSeed();

}  // namespace lt::test
