// The CLI contract of docs/cli.md: outputs and stats keys, and bad input → one line, status 2,
// no output left behind.
#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <tuple>
#include <fstream>
#include <random>
#include <sstream>

#include <nlohmann/json.hpp>

#include "layertrace/util/simd_targets.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/util/image.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "test_util.h"

namespace lt {
namespace {
namespace fs = std::filesystem;

const std::string kDefault = test::sourceDir() + "/scenes/default.json";

nlohmann::json readJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

/// Runs the CLI and requires success (the arguments and stderr are shown otherwise).
void expectRuns(const std::string& args) {
  std::string err;
  ASSERT_EQ(test::runCli(args, &err), 0) << args << "\n" << err;
}

TEST(CliLayers, WritesImagesAndStatsWithTheContractKeys) {
  test::TempDir dir;
  std::string err;
  ASSERT_NO_FATAL_FAILURE(expectRuns("layers " + kDefault + " --width 320 --height 180 --layers 3 --verify --quiet -o " + (dir / "out") +
                             " --stats " + (dir / "s.json")));
  for (const char* f : {"layer0_albedo.png", "layer2_normal.png", "layer1_depth.png", "depth_complexity.png", "depth_complexity.exr"})
    EXPECT_TRUE(fs::exists(dir / ("out/" + std::string(f)))) << f;
  const auto j = readJson(dir / "s.json");
  EXPECT_EQ(j["width"], 320);
  EXPECT_EQ(j["layers"], 3);
  // The machine a time was measured on: the CPU, its threads and the vector target in use.
  const std::string machine = j["machine"].get<std::string>();
  EXPECT_NE(machine.find(" threads, "), std::string::npos) << machine;
  EXPECT_NE(machine.find(activeSimdTarget().name), std::string::npos) << machine;
  for (const char* k : {"total", "depth_complexity_mean", "depth_complexity_max", "overflow"}) EXPECT_TRUE(j["fragments"].contains(k)) << k;
  EXPECT_GT(j["memory_bytes"]["lists"].get<double>(), 0.0);
  EXPECT_GT(j["memory_bytes"]["arrays"].get<double>(), 0.0);
  EXPECT_TRUE(j["timings_ms"].contains("raster") && j["timings_ms"].contains("sort"));
  EXPECT_EQ(j["verify"]["pixels"], 320 * 180);
  EXPECT_GE(j["verify"]["match_fraction"].get<double>(), 0.999);
  // Front faces only: Embree's reference leaves out the back faces too (it matched no pixel).
  ASSERT_NO_FATAL_FAILURE(expectRuns("layers " + kDefault + " --width 320 --height 180 --front-faces-only --verify --quiet -o " + (dir / "ff") +
                                     " --stats " + (dir / "ff.json")));
  EXPECT_GE(readJson(dir / "ff.json")["verify"]["match_fraction"].get<double>(), 0.999);
}

struct BadCase {
  std::string args;
  std::string mustMention;
};

void expectRejected(const BadCase& c, const test::TempDir& dir) {
  std::string err;
  const std::string out = dir / "out.png";
  const int status = test::runCli(c.args + " -o " + out + " --stats " + (dir / "s.json") + " --quiet", &err);
  EXPECT_EQ(status, 2) << c.args << "\n" << err;
  EXPECT_NE(err.find(c.mustMention), std::string::npos) << c.args << "\nstderr: " << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << "one line: " << err;
  EXPECT_FALSE(fs::exists(out)) << c.args;
  EXPECT_FALSE(fs::exists(dir / "s.json")) << c.args;
  for (const auto& e : fs::directory_iterator(dir.path)) ADD_FAILURE() << "left behind: " << e.path() << " by " << c.args;
}

// Which camera a scene file's run looks through: without --camera its own first camera (not
// the one its model brought), and by a name both use, its own.
TEST(CliLayers, SceneFileCamerasBeforeTheModelsCameras) {
  test::TempDir dir;
  test::writeTriangleWithCamera(dir / "tri.gltf");
  std::ofstream(dir / "scene.json") << R"({"objects": [{"model": "tri.gltf"}],
    "cameras": [{"name": "first", "eye": [0.25, 0.25, 4], "target": [0.25, 0.25, 0]},
                {"name": "modelcam", "eye": [0.25, 0.5, 3], "target": [0.25, 0.25, 0]}]})";
  auto eyeOf = [&](const std::string& camera) {
    std::string err;
    const std::string stats = dir / "s.json";
    EXPECT_EQ(test::runCli("layers " + (dir / "scene.json") + camera + " --width 32 --height 18 --quiet -o " + (dir / "out") +
                               " --stats " + stats, &err), 0) << err;
    const nlohmann::json j = nlohmann::json::parse(std::ifstream(stats));
    return j.at("view").at("eye").get<std::vector<double>>();
  };
  EXPECT_EQ(eyeOf(""), (std::vector<double>{0.25, 0.25, 4}));
  EXPECT_EQ(eyeOf(" --camera modelcam"), (std::vector<double>{0.25, 0.5, 3}));
  EXPECT_EQ(eyeOf(" --camera first"), (std::vector<double>{0.25, 0.25, 4}));
}

TEST(CliErrors, BadInputIsOneLineStatusTwoNoOutput) {
  test::TempDir dir, in;
  std::ofstream(in / "bad.json") << "{\n  \"objects\": [\n    {\"box\": {\"min\": [0,0,0] \"max\": [1,1,1]}}\n  ]\n}\n";
  std::ofstream(in / "empty.json") << "{\"objects\": [{\"model\": \"none.obj\"}]}";
  const std::vector<BadCase> cases = {
      {"layers " + in / "nothere.json", "nothere.json"},
      {"layers " + in / "bad.json", "line 3, column"},
      {"layers " + in / "empty.json", "none.obj"},
      {"layers " + kDefault + " --layers 0", "--layers 0"},
      {"layers " + kDefault + " --layers 17", "--layers 17"},
      {"layers " + kDefault + " --width 0", "--width 0"},
      {"layers " + kDefault + " --height -4", "--height -4"},
      {"layers " + kDefault + " --width 30000 --height 30000", "available"},
      {"layers " + kDefault + " --camera nope", "--camera nope"},
      {"layers " + kDefault + " --eye 1,2", "--eye 1,2"},
      {"layers " + kDefault + " --eye 1,2,x", "\"x\""},
      {"layers " + kDefault + " --fov 190", "--fov 190"},
      {"layers " + kDefault + " --thickness -1", "--thickness -1"},
      // 0 is a value, not "use the default" (it was taken as unset before)
      {"layers " + kDefault + " --fov 0", "--fov 0"},
      {"layers " + kDefault + " --thickness 0", "--thickness 0"},
      {"layers " + kDefault + " --thickness-px 0", "--thickness-px 0"},
      {"layers " + kDefault + " --eye 1,2,3 --target 1,2,3", "--eye 1,2,3"},
      {"layers " + kDefault + " --up 0,0,0", "--up 0,0,0"},
      {"layers " + kDefault + " --light 1,2,3,-4", "--light"},
      {"layers " + kDefault + " --width 64 --height 64 --pool 1000", "lost"},
      {"layers " + kDefault + " --bogus", "--bogus"},
      {"frobnicate " + kDefault, "frobnicate"},
  };
  for (const BadCase& c : cases) expectRejected(c, dir);
}

// Found by a sweep of hand-written scene files and option edges.
TEST(CliErrors, SweepFindingsAreRefusedByName) {
  test::TempDir dir, in;
  std::ofstream(in / "deep.json") << R"({"objects": [{"box": {"min": )" << std::string(200000, '[') << std::string(200000, ']')
                                   << R"(, "max": [1,1,1]}}]})";
  std::ofstream(in / "box.json") << R"({"objects": [{"box": {"min": [0,0,0], "max": [1,0,1]}}]})";
  const std::vector<BadCase> cases = {
      {"layers " + in / "deep.json", "nested deeper than 64 levels"},  // crashed (stack overflow)
      {"layers " + in / "box.json", "objects[0].box: box: max must exceed min"},
      {"render " + kDefault + " --tracer ssr --stride 1e9", "--ssr-stride 1e+09"},  // overflowed in the SSR lanes
      {"render " + kDefault + " --tracer ssr --stride inf", "--ssr-stride inf"},
      {"render " + kDefault + " --tracer hssr --tau inf", "--hssr-tau inf"},
      {"render " + kDefault + " --effect ao --ao-radius inf", "--ao-radius inf"},
      {"render " + kDefault + " --max-distance inf", "--max-distance inf"},
      {"layers " + kDefault + " --eye 1e20,1,0 --target 0,0,0", "too far from the scene"},  // an infinite far plane
      {"layers " + kDefault + " --thickness 1e40", "\"1e40\" is out of range"},
      {"layers " + kDefault + " --thickness-px 1e30", "--thickness-px 1e+30: must be in (0, 1e6]"},
      {"layers " + kDefault + " --pool -1", "--pool"},
      {"layers " + kDefault + " --seed -1", "--seed"},
      {"layers " + kDefault + " --max-memory 1K", "--max-memory 1024 bytes"},
      {"compare " + kDefault + " --tracers hssr,grid,hssr", "--tracers hssr: listed twice"},
      {"render " + kDefault + " --preset papers", "--preset papers"},
  };
  for (const BadCase& c : cases) expectRejected(c, dir);
}

// A command writes all its files or none: when one output cannot be written — the last or the
// first — the others it had written are not left behind (they were before: the image and the
// pixel statistics stayed when --stats could not be written).
TEST(CliErrors, AnOutputThatCannotBeWrittenLeavesNoOtherOutput) {
  test::TempDir dir;
  std::ofstream(dir / "a_file") << "x";
  const std::string small = kDefault + " --width 48 --height 27 --quiet";
  const std::vector<std::string> runs = {
      "render " + small + " -o " + (dir / "r/out.png") + " --pixelstats " + (dir / "r/ps") + " --stats /proc/self/nope.json",
      "render " + small + " -o " + (dir / "a_file/x.png") + " --pixelstats " + (dir / "ps2"),
      "compare " + small + " --tracers hssr -o " + (dir / "c") + " --stats /proc/self/nope.json",
      "layers " + small + " -o " + (dir / "l") + " --stats /proc/self/nope.json",
  };
  for (const std::string& args : runs) {
    std::string err;
    EXPECT_EQ(test::runCli(args, &err), 2) << args << "\n" << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    for (const auto& e : fs::directory_iterator(dir.path))
      if (e.path().filename() != "a_file") ADD_FAILURE() << "left behind: " << e.path() << " by " << args;
  }
  // The same commands with writable outputs write every file (upper-case extensions too).
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + small + " -o " + (dir / "r/OUT.PNG") + " --pixelstats " + (dir / "r/ps") + " --stats " + (dir / "r/s.json")));
  for (const char* f : {"r/OUT.PNG", "r/ps/iterations.exr", "r/s.json"}) EXPECT_TRUE(fs::exists(dir / f)) << f;
  // One file written twice by a command (its stats onto its own compare.json) is staged once.
  ASSERT_NO_FATAL_FAILURE(expectRuns("compare " + small + " --tracers hssr -o " + (dir / "c2") + " --stats " + (dir / "c2/compare.json")));
  EXPECT_TRUE(readJson(dir / "c2/compare.json").contains("compare"));
  for (const auto& e : fs::directory_iterator(dir / "c2"))
    EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos) << "left behind: " << e.path();
}

// An image that cannot be written is reported under the name the user gave, not the temporary
// file it was being written to.
TEST(CliErrors, UnwritableImageNamesTheUsersPath) {
  std::string err;
  ASSERT_EQ(test::runCli("render " + kDefault + " --width 32 --height 18 --quiet -o /proc/layertrace_x.png", &err), 2);
  EXPECT_NE(err.find("/proc/layertrace_x.png:"), std::string::npos) << err;
  EXPECT_EQ(err.find(".tmp."), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
}

TEST(CliErrors, RandomBytesAsModelsAreRejectedCleanly) {
  test::TempDir dir;
  test::TempDir inputs;
  std::mt19937_64 rng(test::testSeed());
  for (const char* ext : {".obj", ".glb", ".json"}) {
    std::string bytes(4096, '\0');
    for (char& c : bytes) c = char(rng() & 0xFF);
    const std::string path = inputs / (std::string("noise") + ext);
    std::ofstream(path, std::ios::binary) << bytes;
    expectRejected({"layers " + path, path}, dir);
  }
}

TEST(CliErrors, OverflowReportsExactCounts) {
  std::string err;
  ASSERT_EQ(test::runCli("layers " + kDefault + " --width 64 --height 36 --pool 500 --quiet -o /tmp/layertrace_never", &err), 2);
  // "... N fragments generated, S stored, L lost" with N = S + L
  unsigned long n = 0, s = 0, l = 0;
  const auto pos = err.find("overflow: ");
  ASSERT_NE(pos, std::string::npos) << err;
  ASSERT_EQ(std::sscanf(err.c_str() + pos, "overflow: %lu fragments generated, %lu stored, %lu lost", &n, &s, &l), 3) << err;
  EXPECT_EQ(n, s + l);
  EXPECT_LE(s, 500u);
  EXPECT_GT(l, 0u);
  EXPECT_FALSE(fs::exists("/tmp/layertrace_never"));
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

std::string slurp(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Depth peeling on the CPU: the lists' layers (the same images), k geometry passes, and the
// construction experiment of Hofmann et al. 2017, Fig. 8 against the lists.
TEST(CliLayers, DepthPeelingGivesTheListsLayers) {
  test::TempDir dir;
  const std::string size = " --width 160 --height 90 --layers 3 --quiet";
  for (const char* capture : {"lists", "peel"})
    ASSERT_NO_FATAL_FAILURE(expectRuns("layers " + kDefault + size + " --verify --capture " + capture + " -o " + (dir / capture)));
  const auto lists = readJson(dir / "lists/layers.json"), peel = readJson(dir / "peel/layers.json");
  EXPECT_EQ(peel["capture_pipeline"], "peel");
  EXPECT_EQ(peel["fragments"]["geometry_passes"], 3);
  EXPECT_EQ(peel["fragments"]["rasterized"].get<uint64_t>(), 3 * lists["fragments"]["total"].get<uint64_t>());
  EXPECT_EQ(peel["verify"]["match_fraction"], lists["verify"]["match_fraction"]);
  EXPECT_GE(peel["verify"]["match_fraction"].get<double>(), 0.999);
  for (const char* image : {"layer0_albedo.png", "layer1_depth.png", "layer2_normal.png", "depth_complexity.png"})
    EXPECT_EQ(slurp(dir / (std::string("lists/") + image)), slurp(dir / (std::string("peel/") + image))) << image;
  test::TempDir refused;  // (a refused command writes nothing: checked in an empty folder)
  expectRejected({"layers " + kDefault + " --capture peel --adaptive-thickness", "--adaptive-thickness"}, refused);
  expectRejected({"layers " + kDefault + " --capture peel --pool 100000", "--capture peel"}, refused);
  ASSERT_NO_FATAL_FAILURE(expectRuns("bench " + kDefault + " --experiment peel --repeat 1 --width 96 --height 54 --quiet -o " + (dir / "b")));
  const auto rows = readJson(dir / "b/peel.json")["rows"];
  ASSERT_EQ(rows.size(), 8u);
  EXPECT_GT(rows[0]["lists_bytes"].get<double>(), rows[0]["peel_bytes"].get<double>());  // the lists store every fragment
}

TEST(CliRender, HssrStatsKeysAndSameBytesForOneAndTwoThreads) {
  test::TempDir dir;
  for (int threads : {1, 2}) {
    const std::string n = std::to_string(threads);
    ASSERT_NO_FATAL_FAILURE(expectRuns("render " + kDefault + " --width 240 --height 136 --tracer hssr --effect reflection --bounces 2"
                           " --check-exhaustive --quiet --threads " + n + " -o " + (dir / ("r" + n + ".png")) +
                           " --stats " + (dir / ("s" + n + ".json")) + " --pixelstats " + (dir / "ps")));
  }
  EXPECT_EQ(slurp(dir / "r1.png"), slurp(dir / "r2.png"));
  const auto j = readJson(dir / "s2.json");
  EXPECT_EQ(j["tracer"], "hssr");
  EXPECT_EQ(j["effect"], "reflection");
  for (const char* k : {"count", "hits", "iterations_mean", "iterations_p99", "intervals_per_visited_pixel", "exhaustive_mismatch"})
    EXPECT_TRUE(j["rays"].contains(k)) << k;
  for (const char* k : {"raster", "sort", "hierarchy", "trace", "shade", "total"}) EXPECT_TRUE(j["timings_ms"].contains(k)) << k;
  EXPECT_GT(j["rays"]["count"].get<double>(), 240.0 * 136.0);  // two bounces from most pixels
  // Exactness: HSSR answers every ray exactly as the exhaustive oracle.
  EXPECT_EQ(j["rays"]["exhaustive_mismatch"], 0);
  EXPECT_TRUE(fs::exists(dir / "ps/iterations.exr"));
}

// --preset paper sets each method's paper parameters; a flag given beside it, under its name or
// its older spelling, keeps the user's value; the statistics record the preset and every value.
TEST(CliRender, PaperPresetSetsThePapersParametersAndExplicitFlagsWin) {
  test::TempDir dir;
  const std::string base = "render " + kDefault + " --width 96 --height 54 --tracer hssr --quiet";
  ASSERT_NO_FATAL_FAILURE(expectRuns(base + " --preset paper -o " + (dir / "p.png")));
  ASSERT_NO_FATAL_FAILURE(expectRuns(base + " --preset paper --tau 8 --no-hssr-parent-ascent --ssr-max-steps 0 -o " + (dir / "e.png")));
  ASSERT_NO_FATAL_FAILURE(expectRuns(base + " -o " + (dir / "t.png")));
  const auto p = readJson(dir / "p.json"), e = readJson(dir / "e.json"), t = readJson(dir / "t.json");
  EXPECT_EQ(p["preset"], "paper");
  EXPECT_EQ(t["preset"], "tuned");
  EXPECT_EQ(p["parameters"]["hssr-tau"], 25);
  EXPECT_EQ(p["parameters"]["hssr-levels"], 6);
  EXPECT_EQ(p["parameters"]["hssr-parent-ascent"], false);
  EXPECT_EQ(p["parameters"]["ssr-max-steps"], 25);
  EXPECT_EQ(p["parameters"]["ssr-refine"], false);
  EXPECT_EQ(p["parameters"]["ldc-block-intervals"], 1);
  EXPECT_EQ(p["parameters"]["quadtree-root-start"], true);
  EXPECT_EQ(p["parameters"]["grid-partial-expansion"], false);
  EXPECT_EQ(e["parameters"]["hssr-tau"], 8);          // the older spelling, given explicitly
  EXPECT_EQ(e["parameters"]["hssr-levels"], 6);       // still the preset's
  EXPECT_EQ(e["parameters"]["ssr-max-steps"], 0);     // given explicitly
  EXPECT_EQ(t["parameters"]["hssr-tau"], 4);
  EXPECT_EQ(t["parameters"]["hssr-parent-ascent"], true);
  // The pure n_up ascent visits more cells for the same image.
  EXPECT_GT(p["rays"]["iterations_mean"].get<double>(), t["rays"]["iterations_mean"].get<double>());
  EXPECT_EQ(p["rays"]["hits"], t["rays"]["hits"]);
}

TEST(CliRender, BadTracerAndEffectAreRejected) {
  test::TempDir dir;
  expectRejected({"render " + kDefault + " --tracer bvh", "--tracer bvh"}, dir);
  expectRejected({"render " + kDefault + " --effect glow", "--effect glow"}, dir);
  expectRejected({"render " + kDefault + " --ssr-stride 0", "--ssr-stride 0"}, dir);
  expectRejected({"render " + kDefault + " --hssr-n-up 0", "--hssr-n-up 0"}, dir);
  expectRejected({"render " + kDefault + " --bounces 0", "--bounces 0"}, dir);
  expectRejected({"render " + kDefault + " --tracer hybrid --hybrid-screen ssr", "--hybrid-screen ssr"}, dir);
  expectRejected({"render " + kDefault + " --tracer hybrid --hybrid-geo optix", "--hybrid-geo optix"}, dir);
  expectRejected({"render " + kDefault + " --tracer ldc --ldc-resolution 8", "--ldc-resolution 8"}, dir);
  expectRejected({"compare " + kDefault + " --tracers ldc --ldc-epsilon -1", "--ldc-epsilon -1"}, dir);
  expectRejected({"ldc " + kDefault + " --ldc-block-intervals 0", "--ldc-block-intervals 0"}, dir);
  expectRejected({"ldc " + kDefault + " --ldc-block 300", "--ldc-block 300"}, dir);
  // A memory limit is checked before anything is allocated.
  expectRejected({"render " + kDefault + " --max-memory 1M", "--max-memory 1 MiB: --width/--height 1280x720"}, dir);
  expectRejected({"render " + kDefault + " --max-memory lots", "--max-memory lots"}, dir);
  expectRejected({"compare " + kDefault + " --max-memory 0", "--max-memory 0"}, dir);
}

// The hybrid's stats block (docs/cli.md keys) adds up.
TEST(CliRender, HybridStatsSayWhoAnsweredTheRays) {
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + kDefault + " --width 160 --height 90 --quiet --tracer hybrid --effect reflection -o " +
                                     (dir / "h.png") + " --stats " + (dir / "h.json")));
  const auto j = readJson(dir / "h.json");
  const auto& h = j["hybrid"];
  for (const char* k : {"screen_fraction", "geo_fraction", "geo_length_mean", "screen_ms", "geo_ms", "window_queries_per_ray", "geo_queries_per_ray"})
    ASSERT_TRUE(h.contains(k)) << k;
  EXPECT_EQ(h["rays"], j["rays"]["count"]);
  EXPECT_NEAR(h["screen_fraction"].get<double>() + h["geo_fraction"].get<double>(), 1.0, 1e-9);
  EXPECT_GT(h["screen_fraction"].get<double>(), 0.1);
  EXPECT_GT(h["geo_fraction"].get<double>(), 0.01);
  EXPECT_GT(h["geo_length_mean"].get<double>(), 0.0);
  EXPECT_LE(h["geo_length_mean"].get<double>(), 1.0);
  // Every ray handed to geometry is one query; the windows come on top.
  EXPECT_NEAR(h["geo_queries_per_ray"].get<double>(), h["geo_fraction"].get<double>() + h["window_queries_per_ray"].get<double>(), 1e-9);
  EXPECT_GT(h["window_queries_per_ray"].get<double>(), 0.0);
}

// `layertrace ldc` shows what the layered depth cube captured, and its stats block
// accounts for every triangle and byte; `render --tracer ldc` adds the per-ray visits.
TEST(CliLdc, WritesTheImagesOfEachAxisAndTheStats) {
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(expectRuns("ldc " + kDefault + " --quiet --ldc-resolution 300 -o " + (dir / "ldc") + " --stats " + (dir / "ldc.json")));
  for (const char* axis : {"x", "y", "z"})
    for (const char* image : {"_depth_complexity.png", "_depth_complexity.exr", "_albedo.png"})
      EXPECT_TRUE(fs::exists(dir / (std::string("ldc/ldc_") + axis + image))) << axis << image;
  const auto j = readJson(dir / "ldc.json")["ldc"];
  EXPECT_EQ(j["resolution"], 300);
  uint64_t triangles = 0, samples = 0, memory = 0, lost = 0;
  for (const char* axis : {"x", "y", "z"}) {
    const auto& v = j["views"][axis];
    triangles += v["triangles"].get<uint64_t>(), samples += v["samples"].get<uint64_t>();
    memory += v["memory_bytes"].get<uint64_t>(), lost += v["lost_triangles"].get<uint64_t>();
    EXPECT_GT(v["depth_complexity_max"].get<int>(), 1);
    EXPECT_LE(std::max(v["width"].get<int>(), v["height"].get<int>()), 300);
  }
  EXPECT_EQ(triangles + j["degenerate_triangles"].get<uint64_t>(), readJson(dir / "ldc.json")["triangles"].get<uint64_t>());
  EXPECT_EQ(samples, j["samples"].get<uint64_t>());
  EXPECT_EQ(memory, j["memory_bytes"].get<uint64_t>());
  EXPECT_EQ(lost, j["lost_triangles"].get<uint64_t>());
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + kDefault + " --width 160 --height 90 --quiet --tracer ldc --ldc-resolution 300 -o " +
                                     (dir / "r.png") + " --stats " + (dir / "r.json")));
  const auto r = readJson(dir / "r.json")["ldc"];
  EXPECT_GT(r["blocks_per_ray"].get<double>(), 1.0);
  EXPECT_GT(r["texels_per_ray"].get<double>(), 1.0);
  EXPECT_GT(r["samples_tested_per_ray"].get<double>(), 0.5);
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

TEST(CliRender, EveryEffectAndTracerGivesTheSameBytesForOneAndTwoThreads) {
  test::TempDir dir;
  for (const char* tracer : {"ssr", "ssr-layers", "hiz", "hssr", "quadtree", "ldc", "hybrid", "embree", "grid"})
    for (const char* effect : {"reflection", "refraction", "ao", "shadow", "shade"}) {
      std::string bytes[2];
      for (int threads : {1, 2}) {
        const std::string out = dir / (std::string(tracer) + effect + std::to_string(threads) + ".png");
        ASSERT_NO_FATAL_FAILURE(expectRuns("render " + kDefault + " --width 160 --height 90 --quiet --tracer " + tracer + " --effect " + effect +
                                   " --stride 2 --jitter 0.5 --ao-samples 4 --threads " + std::to_string(threads) + " -o " + out));
        bytes[threads - 1] = slurp(out);
      }
      EXPECT_EQ(bytes[0], bytes[1]) << tracer << " " << effect;
      EXPECT_GT(bytes[0].size(), 1000u);
    }
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

TEST(CliCompare, WritesTheCompareSchemaImagesAndReport) {
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(expectRuns("compare " + kDefault + " --width 200 --height 112 --tracers ssr,hssr --quiet -o " + (dir / "c") +
                             " --report " + (dir / "r") + " --stats " + (dir / "s.json") + " --check-oracle --check-exhaustive"));
  const auto j = readJson(dir / "s.json");
  EXPECT_FALSE(fs::exists(dir / "c/compare.json")) << "--stats names where the statistics go instead";
  for (const char* t : {"ssr", "hssr"}) {
    const auto& c = j["compare"][t];
    double sum = 0.0;
    for (const char* k : {"correct_hit", "wrong_hit", "false_miss", "origin_pixel_miss", "info_miss", "correct_miss"}) {
      ASSERT_TRUE(c.contains(k)) << t << " " << k;
      sum += c[k].get<double>();
    }
    EXPECT_NEAR(sum, 1.0, 1e-9) << t;  // every ray gets exactly one class
    EXPECT_NEAR(c["wrong_hit"].get<double>(),
                c["wrong_hit_thickness"].get<double>() + c["wrong_hit_unstored"].get<double>() + c["wrong_hit_other"].get<double>(), 1e-9);
    for (const char* k : {"exhaustive_mismatch", "oracle_mismatch", "psnr_db", "rmse", "trace_ms", "iterations_mean"})
      EXPECT_TRUE(c.contains(k)) << t << " " << k;
  }
  EXPECT_EQ(j["compare"]["hssr"]["exhaustive_mismatch"], 0);
  // Embree in 16-wide packets traced the same rays with the same answers.
  EXPECT_GT(j["reference"]["packet16_trace_ms"].get<double>(), 0.0);
  EXPECT_EQ(j["reference"]["packet16_traced_rmse"].get<double>(), 0.0);
  EXPECT_GT(j["compare"]["ssr"]["iterations_mean"].get<double>(), j["compare"]["hssr"]["iterations_mean"].get<double>());
  for (const char* f : {"reference.png", "ssr.png", "hssr_classes.png", "side_by_side.png"}) EXPECT_TRUE(fs::exists(dir / ("c/" + std::string(f)))) << f;
  const std::string html = slurp(dir / "r/index.html");
  EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos);
  EXPECT_EQ(html.find("http"), std::string::npos) << "the report must open without a network";
}

TEST(CliBench, WritesCsvJsonWithMachineBuildAndDate) {
  test::TempDir dir;
  for (const char* e : {"tau", "memory"}) {
    ASSERT_NO_FATAL_FAILURE(expectRuns(std::string("bench ") + kDefault + " --experiment " + e + " --width 160 --height 90 --repeat 1 --quiet -o " +
                               (dir / "b")));
    const auto j = readJson(dir / ("b/" + std::string(e) + ".json"));
    for (const char* k : {"machine", "build_type", "date", "scene", "rows", "repeat"}) EXPECT_TRUE(j.contains(k)) << e << " " << k;
    EXPECT_TRUE(fs::exists(dir / ("b/" + std::string(e) + ".csv")));
    ASSERT_FALSE(j["rows"].empty());
    if (std::string(e) == "tau") {
      EXPECT_EQ(j["rows"].size(), 9u);
      for (const auto& r : j["rows"]) EXPECT_GT(r["trace_ms"].get<double>(), 0.0);
    } else {
      EXPECT_EQ(j["rows"].size(), 2u);
      // 1080p holds 2.25× the pixels of 720p: every per-pixel buffer grows with it.
      EXPECT_GT(j["rows"][1]["arrays_bytes"].get<double>(), 2.2 * j["rows"][0]["arrays_bytes"].get<double>());
    }
  }
  test::TempDir clean;
  expectRejected({"bench " + kDefault + " --experiment glow", "--experiment glow"}, clean);
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

TEST(CliGeobench, StatsKeysAndAgreement) {
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(expectRuns("geobench " + kDefault + " --width 160 --height 90 --repeat 1 --sweep --quiet -o " + (dir / "g") +
                             " --stats " + (dir / "s.json")));
  const auto j = readJson(dir / "s.json");
  for (const char* t : {"grid", "embree"})
    for (const char* k : {"build_ms", "memory_bytes", "mrays_primary", "mrays_ao", "mrays_diffuse", "agreement_primary",
                          "agreement_ao", "agreement_diffuse"}) {
      ASSERT_TRUE(j["geobench"][t].contains(k)) << t << " " << k;
      if (std::string(k).rfind("agreement", 0) == 0) {
        EXPECT_GE(j["geobench"][t][k].get<double>(), 0.9999) << t << " " << k;
      }
    }
  // Agreement counting robust Embree where plain Embree slipped through an edge: the grid answers
  // as the watertight reference on every ray, and never less than it agrees with plain Embree.
  for (const char* set : {"primary", "ao", "diffuse"}) {
    const double robust = j["geobench"]["grid"][std::string("agreement_robust_") + set].get<double>();
    EXPECT_EQ(robust, 1.0) << set;
    EXPECT_GE(robust, j["geobench"]["grid"][std::string("agreement_") + set].get<double>()) << set;
  }
  // Every λ setting of the sweep answers like Embree (the speed is the README's to compare).
  std::ifstream sweep(dir / "g/geobench_sweep.csv");
  std::string line;
  ASSERT_TRUE(std::getline(sweep, line));
  EXPECT_EQ(line.substr(line.rfind(',') + 1), "agreement_min");
  int settings = 0;
  for (; std::getline(sweep, line); ++settings) EXPECT_GE(std::stod(line.substr(line.rfind(',') + 1)), 0.9999) << line;
  EXPECT_EQ(settings, 7 * 4);
  test::TempDir clean;
  expectRejected({"geobench " + kDefault + " --lambda1 0", "--grid-lambda1 0"}, clean);
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// assimp's OFF importer crashes on a face with a negative vertex count: still one line, status 2
// (the import guard, scene/load_model.cpp).
TEST(CliErrors, ImporterCrashIsReportedAsMalformedModel) {
  test::TempDir dir, in;
  std::ofstream(in / "crash.off") << "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n-5 0 1 2\n";
  expectRejected({"render " + in / "crash.off", "crash.off: the model importer crashed"}, dir);
}

// assimp's own OutOfMemory.off declares 353 535 235 358 vertices in 309 bytes: refused from its
// header, before assimp reads it (assimp's importer ran 85 s before it died; the message comes
// only from the header check).
TEST(CliErrors, OffHeaderDeclaringMoreThanTheFileHoldsIsRefused) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  test::TempDir dir;
  expectRejected({"render " + test::sourceDir() + "/data/models/invalid/OutOfMemory.off", "OutOfMemory.off: the OFF header declares 353535235358"},
                 dir);
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// On a scene without mirror materials the final images of all tracers are the same
// (nothing reflects), but the traced radiance differs: psnr_traced_db is finite and tells the
// tracers apart.
// A view that shows nothing casts no rays: the table says so and prints no class shares (0 %
// correct of no rays would read as a failure).
// --quiet keeps stdout silent while a model imports too: assimp 5.2.5's Ogre reader prints
// "Skeleton is not a valid root" with printf for every skeleton it reads (found by a sweep of assimp's models,
// assimp's fish.mesh.xml and ninja.mesh.xml).
TEST(CliRender, QuietStaysQuietWhileAnImporterChatters) {
  test::TempDir dir, in;
  std::ofstream(in / "t.mesh.xml") << R"(<mesh><submeshes>
  <submesh material="m" usesharedvertices="false" use32bitindexes="false" operationtype="triangle_list">
    <faces count="1"><face v1="0" v2="1" v3="2"/></faces>
    <geometry vertexcount="3"><vertexbuffer positions="true">
      <vertex><position x="0" y="0" z="0"/></vertex><vertex><position x="1" y="0" z="0"/></vertex>
      <vertex><position x="0" y="1" z="0"/></vertex></vertexbuffer></geometry></submesh></submeshes>
  <skeletonlink name="t.skeleton.xml"/></mesh>)";
  std::ofstream(in / "t.skeleton.xml") << R"(<skeleton><bones><bone id="0" name="root"><position x="0" y="0" z="0"/>
  <rotation angle="0"><axis x="1" y="0" z="0"/></rotation></bone></bones><bonehierarchy/></skeleton>)";
  std::string err, out;
  ASSERT_EQ(test::runCli("render " + in / "t.mesh.xml" + " --width 16 --height 12 --quiet -o " + dir / "t.png", &err, &out), 0) << err;
  EXPECT_EQ(out, "");
  EXPECT_EQ(err, "");
  EXPECT_TRUE(fs::exists(dir / "t.png"));
  // Without --quiet the run's own summary still reaches stdout.
  ASSERT_EQ(test::runCli("render " + in / "t.mesh.xml" + " --width 16 --height 12 -o " + dir / "u.png", &err, &out), 0) << err;
  EXPECT_NE(out.find("render: "), std::string::npos) << out;
  EXPECT_EQ(out.find("Skeleton"), std::string::npos) << out;
}

TEST(CliCompare, ViewWithoutRaysSaysSo) {
  test::TempDir dir;
  std::string err, out;
  const std::string args = "compare " + kDefault + " --eye 0,0,1000 --target 0,0,2000 --width 64 --height 36 --tracers hssr,hybrid -o " + (dir / "c");
  ASSERT_EQ(test::runCli(args, &err, &out), 0) << err;
  EXPECT_NE(out.find("no rays: no covered pixel of this view casts reflection rays"), std::string::npos) << out;
  EXPECT_EQ(out.find('%'), std::string::npos) << out;
  EXPECT_EQ(readJson(dir / "c/compare.json")["reference"]["rays"], 0);
}

TEST(CliCompare, TracedPsnrIsFiniteAndDiffersWithoutMirrorMaterials) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(expectRuns("compare " + test::sourceDir() + "/scenes/cornell-box.json --camera interior --width 160 --height 90"
                                     " --tracers ssr,hssr --quiet -o " + (dir / "c")));
  const auto j = readJson(dir / "c/compare.json");
  const double ssr = j["compare"]["ssr"]["psnr_traced_db"].get<double>(), hssr = j["compare"]["hssr"]["psnr_traced_db"].get<double>();
  EXPECT_LT(ssr, 60.0);
  EXPECT_LT(hssr, 60.0);
  EXPECT_GT(ssr, 0.0);
  EXPECT_NE(ssr, hssr);
  EXPECT_TRUE(std::filesystem::exists(dir / "c/hssr_traced.png"));
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

/// Runs `bench --experiment NAME` on the default scene at W × H (one repeat); its JSON.
nlohmann::json benchOnDefaultScene(const std::string& experiment, int w, int h) {
  test::TempDir dir;
  expectRuns("bench " + kDefault + " --experiment " + experiment + " --width " + std::to_string(w) + " --height " + std::to_string(h) +
             " --repeat 1 --quiet -o " + (dir / "b"));
  return readJson(dir / ("b/" + experiment + ".json"));
}

// bench --experiment warp sweeps offsets × k × screen tracers; holes grow with the
// offset, never with k for the multi-layer tracers, and are zero without an offset.
TEST(CliBench, WarpSweepsOffsetsLayersAndTracers) {
  nlohmann::json j;
  ASSERT_NO_FATAL_FAILURE(j = benchOnDefaultScene("warp", 160, 90));
  ASSERT_EQ(j["rows"].size(), 5u * 3u * 5u);
  std::map<std::tuple<std::string, int, double>, double> holes;
  for (const auto& r : j["rows"]) holes[{r["tracer"].get<std::string>(), r["k"].get<int>(), r["offset"].get<double>()}] = r["hole_fraction"].get<double>();
  for (const auto& [key, h] : holes) {
    const auto& [tracer, k, offset] = key;
    if (offset == 0.0) {
      EXPECT_EQ(h, 0.0) << tracer << " k " << k;
    }
    if ((tracer == "hssr" || tracer == "quadtree") && k > 1) {
      const double fewer = holes[std::make_tuple(tracer, k / 2, offset)];
      EXPECT_LE(h, fewer) << "k " << k << " offset " << offset;
    }
  }
  const double far = holes[std::make_tuple(std::string("hssr"), 1, double(0.2f))];
  const double near = holes[std::make_tuple(std::string("hssr"), 1, double(0.025f))];
  EXPECT_GT(far, near);
}

// Widmer et al. 2015 give no γ: bench --experiment gamma sweeps the quad-tree's merge
// thresholds. γ = 0 merges nothing, so it answers exactly as the unmerged tree; looser γ merges
// plane nodes above level 0.
TEST(CliBench, GammaSweepsTheQuadtreeMergeThresholds) {
  nlohmann::json j;
  ASSERT_NO_FATAL_FAILURE(j = benchOnDefaultScene("gamma", 160, 90));
  const auto& rows = j["rows"];
  ASSERT_EQ(rows.size(), 17u);
  EXPECT_EQ(rows[0]["gamma_dist"].get<double>(), 0.0);
  EXPECT_EQ(rows[0]["plane_nodes_above_level0"].get<uint64_t>(), 0u);
  EXPECT_EQ(rows[0]["changed_vs_unmerged"].get<double>(), 0.0);
  const auto& loosest = rows[rows.size() - 1];
  EXPECT_GT(loosest["plane_nodes_above_level0"].get<uint64_t>(), 0u);
  for (const auto& r : rows) EXPECT_GT(r["correct_hit"].get<double>(), 0.3);
}

// bench --experiment ldc sweeps 512² and 1K² × blocks 4, 8, 16 (and the paper's
// min/max) beside Embree and HSSR; the blocks change no answer, the finer LDIs store more.
TEST(CliBench, LdcSweepsResolutionAndBlocks) {
  nlohmann::json j;
  ASSERT_NO_FATAL_FAILURE(j = benchOnDefaultScene("ldc", 160, 90));
  const auto& rows = j["rows"];
  ASSERT_EQ(rows.size(), 10u);
  EXPECT_EQ(rows[0]["tracer"], "embree");
  EXPECT_EQ(rows[1]["tracer"], "hssr");
  for (size_t i = 2; i < rows.size(); ++i) {
    const auto& r = rows[i];
    EXPECT_EQ(r["tracer"], "ldc");
    EXPECT_EQ(r["correct_hit"], rows[i < 6 ? 2 : 6]["correct_hit"]) << "blocks changed answers, row " << i;
    EXPECT_GT(r["correct_hit"].get<double>(), rows[1]["correct_hit"].get<double>()) << "row " << i;
    EXPECT_GT(r["trace_ms"].get<double>(), 0.0);
  }
  EXPECT_GT(rows[6]["samples"].get<uint64_t>(), 3 * rows[2]["samples"].get<uint64_t>());  // 1K² vs 512²
  EXPECT_EQ(rows[5]["block_intervals"], 1);
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// bench --experiment capture times raster, sort and pyramid per thread count beside
// Embree's all-hit capture of the same pixel-centre rays, which must find the same fragments.
TEST(CliBench, CaptureAgainstEmbreeAllHitsOfTheSameRays) {
  nlohmann::json j;
  ASSERT_NO_FATAL_FAILURE(j = benchOnDefaultScene("capture", 200, 120));
  ASSERT_FALSE(j["rows"].empty());
  int tiles = 0, lists = 0, reference = 0;
  for (const auto& r : j["rows"]) {
    for (const char* k : {"raster_ms", "pyramid_ms", "embree_allhit_ms", "mfragments_per_s"}) EXPECT_GT(r[k].get<double>(), 0.0) << k;
    const double fragments = r["fragments"].get<double>(), hits = r["embree_hits"].get<double>();
    EXPECT_NEAR(hits, fragments, 1e-3 * fragments) << "Embree and the rasterizer capture the same surfaces";
    EXPECT_EQ(r["fragments"], j["rows"][0]["fragments"]) << "every pipeline rasterizes the same fragments";
    if (r["pipeline"] == "tiles") {
      ++tiles;
      EXPECT_EQ(r["sort_ms"].get<double>(), 0.0) << "the tile-local pass sorts while it rasterizes";
      EXPECT_LT(r["lists_bytes"].get<double>(), 8.0 * 200 * 120) << "no fragment storage, only per-pixel counts";
    } else if (r["pipeline"] == "tiles+lists") {
      ++lists;
      EXPECT_EQ(r["lists_bytes"].get<double>(), 20.0 * fragments + 8.0 * 200 * 120) << "exact-size lists: 16 + 4 bytes per fragment";
    } else {
      ++reference;
      EXPECT_EQ(r["pipeline"], "reference");
      EXPECT_GT(r["sort_ms"].get<double>(), 0.0);
      EXPECT_GE(r["lists_bytes"].get<double>(), 20.0 * 8 * 200 * 120) << "the reference pool starts at 8 fragments per pixel";
    }
  }
  EXPECT_EQ(tiles, lists);
  EXPECT_EQ(tiles, reference);
  EXPECT_GE(tiles, 1);
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

/// The default scene moved by `offset` (objects, lights, cameras) into `dir`/far.json.
std::string movedDefaultScene(const test::TempDir& dir, const std::array<double, 3>& offset) {
  std::ifstream in(kDefault);
  nlohmann::json s = nlohmann::json::parse(in, nullptr, true, true);
  auto move = [&](nlohmann::json& p) {
    for (int a = 0; a < 3; ++a) p[a] = p[a].get<double>() + offset[a];
  };
  for (auto& o : s["objects"]) {
    if (o.contains("model")) o["model"] = test::sourceDir() + "/scenes/" + o["model"].get<std::string>();
    nlohmann::json& t = o["transform"];  // translate · rotate · scale: the offset adds to translate
    if (!t.contains("translate")) t["translate"] = {0.0, 0.0, 0.0};
    move(t["translate"]);
  }
  for (auto& l : s["lights"]) move(l["position"]);
  for (auto& c : s["cameras"]) move(c["eye"]), move(c["target"]);
  const std::string path = dir / "far.json";
  std::ofstream(path) << s.dump();
  return path;
}

// A scene 10⁵ units from the origin of its file is moved next to the origin on load
// (scene/scene.h recentre): every tracer then computes as precisely as on the same scene at the
// origin, while every coordinate the user gives or reads stays in the file's coordinates. Before,
// plain and robust Embree disagreed there and `layers --verify` matched a third of the pixels.
TEST(CliWorld, AFarSceneIsTracedAsWellAsTheSameSceneAtTheOrigin) {
  test::TempDir dir;
  const std::array<double, 3> offset{100000.0, 25000.0, -150000.0};
  const std::string far = movedDefaultScene(dir, offset);
  const std::string size = " --width 240 --height 135 --quiet";
  ASSERT_NO_FATAL_FAILURE(expectRuns("layers " + far + size + " --verify -o " + (dir / "l") + " --stats " + (dir / "l.json")));
  const auto l = readJson(dir / "l.json");
  EXPECT_GE(l["verify"]["match_fraction"].get<double>(), 0.999);
  // Stats are in the file's coordinates: the camera as the file gives it (a scene file's numbers
  // are floats: 1/128 apart out there), the bounds around it.
  for (int a = 0; a < 3; ++a) {
    const double eye[] = {0.0, 1.5, 1.85};
    EXPECT_NEAR(l["view"]["eye"][a].get<double>(), eye[a] + offset[a], 1.0 / 128) << a;
    EXPECT_LT(l["bounds"][0][a].get<double>(), offset[a] + 0.01);
    EXPECT_GT(l["bounds"][1][a].get<double>(), offset[a] + 0.01);
  }
  // The hybrid's answers are the reference's on a far scene as near the origin.
  ASSERT_NO_FATAL_FAILURE(expectRuns("compare " + far + size + " --tracers hybrid,grid -o " + (dir / "c")));
  const auto c = readJson(dir / "c/compare.json")["compare"];
  EXPECT_GE(c["hybrid"]["correct_hit"].get<double>() + c["hybrid"]["correct_miss"].get<double>(), 0.995);
  EXPECT_GE(c["grid"]["correct_hit"].get<double>() + c["grid"]["correct_miss"].get<double>(), 0.9999);
  // A view given on the command line is in the file's coordinates too (and --light, --warp-eye).
  auto at = [&](double x, double y, double z) {  // offset + (x, y, z) as the command line gives it
    std::ostringstream t;
    t.precision(17);
    t << offset[0] + x << "," << offset[1] + y << "," << offset[2] + z;
    return t.str();
  };
  const std::string eye = at(1.4, 0.4, 1.5), target = at(-0.5, 0.6, -1.5);
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + far + size + " --tracer embree --eye " + eye + " --target " + target +
                                      " --light " + at(0.0, 2.7, -0.5) + ",6" +
                                     " -o " + (dir / "far.png") + " --stats " + (dir / "farview.json")));
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + kDefault + size + " --tracer embree --eye 1.4,0.4,1.5 --target -0.5,0.6,-1.5 --light 0,2.7,-0.5,6 -o " +
                                     (dir / "near.png") + " --stats " + (dir / "near.json")));
  EXPECT_NEAR(readJson(dir / "farview.json")["view"]["target"][2].get<double>(), offset[2] - 1.5, 1e-9);
  const Image a = readImage(dir / "far.png"), b = readImage(dir / "near.png");
  ASSERT_EQ(a.data.size(), b.data.size());
  size_t differ = 0;  // the same picture, but for the bunny's vertices, rounded to 1/128 out there
  for (size_t i = 0; i < a.data.size(); ++i) differ += std::abs(a.data[i] - b.data[i]) > 0.1f;
  EXPECT_LT(differ, a.data.size() / 50);
  // View synthesis: the second eye in the file's coordinates too, reported back in them.
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + far + size + " --tracer hssr --effect warp --warp-eye " + at(0.3, 1.4, 1.8) + " -o " +
                                     (dir / "wf.png") + " --stats " + (dir / "wf.json")));
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + kDefault + size + " --tracer hssr --effect warp --warp-eye 0.3,1.4,1.8 -o " + (dir / "wn.png") +
                                     " --stats " + (dir / "wn.json")));
  const auto wf = readJson(dir / "wf.json")["warp"], wn = readJson(dir / "wn.json")["warp"];
  EXPECT_NEAR(wf["eye"][0].get<double>(), offset[0] + 0.3, 1.0 / 128);
  EXPECT_NEAR(wf["hole_fraction"].get<double>(), wn["hole_fraction"].get<double>(), 0.01);
  EXPECT_NEAR(wf["psnr_db"].get<double>(), wn["psnr_db"].get<double>(), 1.5);
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// One output convention (docs/cli.md): -o is the main output, and a command's statistics land
// beside it without being asked for: <image stem>.json for render, <folder>/<command>.json for
// the others. --pixelstats and --report without a folder write beside the main output too.
TEST(CliConvention, StatisticsLandBesideTheMainOutputByDefault) {
  test::TempDir dir;
  const std::string small = kDefault + " --width 96 --height 64 --layers 2 --quiet";
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + small + " -o " + (dir / "r/img.png") + " --pixelstats"));
  EXPECT_EQ(readJson(dir / "r/img.json")["width"], 96);
  EXPECT_TRUE(fs::exists(dir / "r/img_pixelstats/iterations.exr"));
  ASSERT_NO_FATAL_FAILURE(expectRuns("compare " + small + " --tracers hssr,ssr -o " + (dir / "c") + " --report --pixelstats"));
  EXPECT_TRUE(readJson(dir / "c/compare.json").contains("compare"));
  EXPECT_TRUE(fs::exists(dir / "c/index.html"));
  for (const char* t : {"hssr", "ssr"}) EXPECT_TRUE(fs::exists(dir / ("c/pixelstats/" + std::string(t) + "/iterations.exr"))) << t;
  // A common option the command has no use for is named in a warning, not passed over in silence.
  std::string err;
  ASSERT_EQ(test::runCli("layers " + small + " -o " + (dir / "l") + " --pixelstats --light 1,2,3", &err), 0) << err;
  EXPECT_NE(err.find("layers does not use --light"), std::string::npos) << err;
  EXPECT_EQ(readJson(dir / "l/layers.json")["layers"], 2);
  const Image fragments = readImage(dir / "l/pixelstats/fragments.exr");
  EXPECT_EQ(fragments.width, 96);
  ASSERT_NO_FATAL_FAILURE(expectRuns("geobench " + small + " --repeat 1 -o " + (dir / "g")));
  EXPECT_TRUE(fs::exists(dir / "g/geobench.json"));
  // --stats names another file: the statistics go there instead.
  ASSERT_NO_FATAL_FAILURE(expectRuns("layers " + small + " -o " + (dir / "l2") + " --stats " + (dir / "elsewhere.json")));
  EXPECT_EQ(readJson(dir / "elsewhere.json")["layers"], 2);
  EXPECT_FALSE(fs::exists(dir / "l2/layers.json"));
}

/// rays.iterations_mean of a small render with `flags`.
double iterationsWith(const std::string& flags, const test::TempDir& dir) {
  const std::string stats = dir / "s.json";
  std::string err;
  EXPECT_EQ(test::runCli("render " + kDefault + " --width 96 --height 64 --layers 2 --quiet -o " + (dir / "r.png") + " --stats " + stats +
                             " " + flags,
                         &err),
            0)
      << flags << "\n"
      << err;
  return readJson(stats)["rays"]["iterations_mean"].get<double>();
}

// Every method parameter has a namespaced flag; its older spelling is a hidden alias that sets
// the same field (the run's iterations equal, and differ from the default's).
TEST(CliConvention, OlderFlagSpellingsSetTheSameParameters) {
  test::TempDir dir;
  struct Case {
    std::string tracer, flag, alias, value;
  };
  for (const Case& c : {Case{"ssr", "--ssr-stride", "--stride", "4"}, Case{"ssr", "--ssr-max-steps", "--max-steps", "3"},
                        Case{"hssr", "--hssr-levels", "--levels", "1"}, Case{"hssr", "--hssr-n-up", "--n-up", "6"}}) {
    const double defaults = iterationsWith("--tracer " + c.tracer, dir);
    const double named = iterationsWith("--tracer " + c.tracer + " " + c.flag + " " + c.value, dir);
    const double aliased = iterationsWith("--tracer " + c.tracer + " " + c.alias + " " + c.value, dir);
    EXPECT_EQ(named, aliased) << c.flag;
    EXPECT_NE(named, defaults) << c.flag << " had no effect";
  }
  // The aliases stay out of the help text; the namespaced flags are in it.
  std::string out;
  ASSERT_EQ(test::runCli("render --help", nullptr, &out), 0);
  EXPECT_NE(out.find("--hssr-tau"), std::string::npos);
  EXPECT_EQ(out.find("--tau "), std::string::npos);
  // A switch shows its default and its off spelling in words, not CLI11's "{false}".
  EXPECT_EQ(out.find("{false}"), std::string::npos);
  EXPECT_NE(out.find("(default on; --no-hssr-parent-ascent turns it off)"), std::string::npos);
  // Every --repeat of the measuring commands reads the same.
  std::string help;
  for (const char* cmd : {"bench", "reproduce", "geobench"}) {
    ASSERT_EQ(test::runCli(std::string(cmd) + " --help", nullptr, &help), 0);
    EXPECT_NE(help.find("timed runs of each measured time; the median is reported"), std::string::npos) << cmd;
  }
}

// `layertrace tracers` lists every tracer of the registry with its parameters and defaults, and
// `--version` the version CMake gave the project.
TEST(CliConvention, TracersAndVersionDescribeTheBuild) {
  std::string out;
  ASSERT_EQ(test::runCli("tracers", nullptr, &out), 0);
  for (const TracerEntry& e : tracerRegistry()) EXPECT_NE(out.find(std::string("\n  ") + e.info.name + ": "), std::string::npos) << e.info.name;
  const TracerOptions defaults;
  for (const TracerParam& p : tracerParams())
    EXPECT_NE(out.find(std::string(p.flag) + " " + paramValue(p, defaults) + " "), std::string::npos) << p.flag;
  for (const char* effect : {"shade", "reflection", "refraction", "ao", "shadow", "warp"}) EXPECT_NE(out.find(effect), std::string::npos);
  // Each tracer lists exactly the parameters it reads: Hi-Z the level count alone.
  for (const TracerEntry& e : tracerRegistry()) {
    const size_t at = out.find(std::string("\n  ") + e.info.name + ": ");
    const std::string section = out.substr(at, out.find("\n\n", at + 1) - at);
    for (const TracerParam& p : tracerParams())
      EXPECT_EQ(section.find(std::string("    ") + p.flag + " ") != std::string::npos, e.reads(p)) << e.info.name << " " << p.flag;
  }
  const TracerEntry* hiz = findTracer("hiz");
  ASSERT_NE(hiz, nullptr);
  EXPECT_EQ(std::count_if(tracerParams().begin(), tracerParams().end(), [&](const TracerParam& p) { return hiz->reads(p); }), 1);
  ASSERT_EQ(test::runCli("--version", nullptr, &out), 0);
  EXPECT_EQ(out.rfind(std::string("layertrace ") + LAYERTRACE_VERSION_TEST + " (commit ", 0), 0u) << out;
  // No arguments: the help on stdout, status 0; options without a subcommand: one line, status 2.
  std::string err;
  ASSERT_EQ(test::runCli("", &err, &out), 0);
  EXPECT_NE(out.find("render"), std::string::npos) << out;
  EXPECT_NE(out.find("Usage"), std::string::npos) << out;
  EXPECT_EQ(test::runCli("--threads 2", &err), 2);
  EXPECT_EQ(err.rfind("layertrace: ", 0), 0u) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
}

// compare checks image-space rays against the exhaustive oracle unless told not to.
TEST(CliConvention, CompareTheExhaustiveCheckCanBeTurnedOff) {
  test::TempDir dir;
  const std::string args = "compare " + kDefault + " --width 96 --height 64 --layers 2 --quiet --tracers hssr -o ";
  ASSERT_NO_FATAL_FAILURE(expectRuns(args + (dir / "on")));
  ASSERT_NO_FATAL_FAILURE(expectRuns(args + (dir / "off") + " --no-check-exhaustive"));
  EXPECT_EQ(readJson(dir / "on/compare.json")["compare"]["hssr"]["exhaustive_mismatch"], 0);
  EXPECT_FALSE(readJson(dir / "off/compare.json")["compare"]["hssr"].contains("exhaustive_mismatch"));
}

// --device gpu: the GPU tracers, with the effect's rays generated and shaded on the GPU, give the
// CPU's image (the same fragments; GLSL's pow is not libm's, so a colour may round to the
// neighbouring 8-bit value), and compare traces the CPU's rays again on the GPU and reports the
// agreement.
TEST(CliGpu, RenderOnTheGpuGivesTheCpuImage) {
  if (!gpuBuilt()) GTEST_SKIP() << "built without the GPU back end";
  test::TempDir dir;
  for (const std::string t : {"ssr", "hiz", "hssr"})
    for (const std::string effect : {"reflection --bounces 2", "ao --ao-samples 2"}) {
      const std::string common = "render " + kDefault + " --width 200 --height 120 --quiet --tracer " + t + " --effect " + effect;
      ASSERT_NO_FATAL_FAILURE(expectRuns(common + " -o " + (dir / "cpu.png")));
      ASSERT_NO_FATAL_FAILURE(expectRuns(common + " --device gpu -o " + (dir / "gpu.png")));
      const Image a = readImage(dir / "cpu.png", false), b = readImage(dir / "gpu.png", false);
      ASSERT_EQ(a.data.size(), b.data.size());
      // The GPU run captures on the GPU: where its rasterizer takes the other of two surfaces that
      // meet at a pixel centre (1 of the 96,000 pixel-layers at this size, which `layers --device
      // gpu --verify` reports as gpu_vs_cpu), that pixel's rays differ. At most 1 value in 10,000
      // may differ by more than one 8-bit step; every other value is the CPU's within one step.
      size_t offByOne = 0, beyond = 0;
      for (size_t i = 0; i < a.data.size(); ++i) {
        const float d = std::abs(a.data[i] - b.data[i]) * 255.0f;
        beyond += d >= 1.5f;
        offByOne += d > 0.5f;
      }
      EXPECT_LE(beyond, a.data.size() / 10000) << t << " " << effect;
      EXPECT_LE(offByOne, a.data.size() / 1000) << t << " " << effect;
      const auto j = readJson(dir / "gpu.json");
      EXPECT_EQ(j["device"], "gpu");
      EXPECT_EQ(j["gpu"]["shading"], "gpu");
      EXPECT_GT(j["memory_bytes"]["gpu_effect"].get<double>(), 0.0);
      // The same rays and answers (tests/gpu_effects_test.cpp bounds the rare ray whose
      // direction takes GLSL's sin and cos, or a GPU's approximate division, across a boundary).
      const auto c = readJson(dir / "cpu.json")["rays"];
      for (const char* key : {"count", "hits", "iterations_mean"})
        EXPECT_NEAR(j["rays"][key].get<double>(), c[key].get<double>(), 1e-3 * c[key].get<double>()) << t << " " << key;
      EXPECT_FALSE(j["gpu_renderer"].get<std::string>().empty());
      EXPECT_GT(j["timings_ms"]["gpu_trace"].get<double>(), 0.0);
      if (t == "hssr") {
        // The pyramid's intervals per level, as the GPU's build counted them (not read back).
        const auto g = j["hssr"]["intervals_per_level"], h = readJson(dir / "cpu.json")["hssr"]["intervals_per_level"];
        ASSERT_EQ(g.size(), h.size());
        ASSERT_GT(g.size(), 1u);
        for (size_t l = 0; l < g.size(); ++l) EXPECT_NEAR(g[l].get<double>(), h[l].get<double>(), 1e-3 * h[l].get<double>()) << "level " << l;
      }
      EXPECT_EQ(readJson(dir / "cpu.json")["device"], "cpu");
    }
}

// render --device gpu is one resident frame: capture, sort, pyramid, march and effect on the
// device, one host wait, nothing read back but the picture and the frame's counters. Every
// statistic of the rays and of the capture is reduced on the device and equals the CPU's (to the
// bit on llvmpipe). A per-ray check (--check-oracle) needs the layers on the host: not resident.
TEST(CliGpu, RenderIsOneResidentFrameWithTheCpusStatistics) {
  if (!gpuBuilt()) GTEST_SKIP() << "built without the GPU back end";
  test::TempDir dir;
  const int W = 160, H = 96;
  for (const std::string t : {"hssr", "hiz", "ssr", "ssr-layers", "quadtree", "ldc", "grid"})
    for (const std::string effect : {"reflection --bounces 3", "ao --ao-samples 2", "refraction"}) {
      // (the quad-tree and the tracers of the scene: reflections, for the test's time; their AO in
      // tests/gpu_frame_test.cpp)
      if ((t == "quadtree" || t == "ldc" || t == "grid") && !effect.starts_with("reflection")) continue;
      const std::string common = "render " + kDefault + " --width 160 --height 96 --quiet --tracer " + t + " --effect " + effect;
      ASSERT_NO_FATAL_FAILURE(expectRuns(common + " -o " + (dir / "cpu.png")));
      ASSERT_NO_FATAL_FAILURE(expectRuns(common + " --device gpu -o " + (dir / "gpu.png")));
      const auto g = readJson(dir / "gpu.json"), c = readJson(dir / "cpu.json");
      const std::string what = t + " " + effect;
      EXPECT_EQ(g["gpu"]["resident"], true) << what;
      EXPECT_EQ(g["capture_pipeline"], "gpu-lists") << what;
      const auto& frame = g["gpu"]["frame"];
      EXPECT_EQ(frame["host_waits"], 1) << what;
      EXPECT_EQ(frame["draws"], 1) << what;
      // The picture (RGBA8, the PNG's sRGB codes packed on the device) and the counter block.
      EXPECT_LE(frame["download_bytes"].get<double>(), double(W * H * 4 + 1024)) << what;
      const bool exact = g["gpu"]["software"].get<bool>();
      const auto same = [&](const nlohmann::json& a, const nlohmann::json& b, const std::string& key) {
        if (exact || !a.is_number()) EXPECT_EQ(a, b) << what << ": " << key;
        else EXPECT_NEAR(a.get<double>(), b.get<double>(), 1e-3 * std::abs(b.get<double>()) + 1.0) << what << ": " << key;
      };
      for (const char* key : {"count", "hits", "iterations_mean", "iterations_p99", "visited_pixels_mean", "give_ups", "bent",
                              "intervals_per_visited_pixel"}) {
        EXPECT_EQ(g["rays"].contains(key), c["rays"].contains(key)) << what << ": rays." << key;
        if (c["rays"].contains(key) && g["rays"].contains(key)) same(g["rays"][key], c["rays"][key], std::string("rays.") + key);
      }
      for (const char* key : {"total", "stored", "depth_complexity_mean", "depth_complexity_max", "overflow"})
        same(g["fragments"][key], c["fragments"][key], std::string("fragments.") + key);
      same(g["memory_bytes"]["arrays"], c["memory_bytes"]["arrays"], "memory_bytes.arrays");
      // The structures' own statistics: the quad-tree's nodes and visits, the cube's samples.
      if (t == "quadtree" || t == "ldc") {
        ASSERT_TRUE(g.contains(t)) << what;
        const std::function<nlohmann::json(nlohmann::json)> untimed = [&](nlohmann::json j) {  // without the *_ms keys
          if (!j.is_object()) return j;
          nlohmann::json out = nlohmann::json::object();
          for (const auto& [key, value] : j.items())
            if (!key.ends_with("_ms")) out[key] = untimed(value);
          return out;
        };
        const nlohmann::json want = untimed(c[t]), got = untimed(g[t]);
        for (const auto& [key, value] : want.items()) same(got[key], value, t + "." + key);
      }
      if (t == "hssr") {
        same(g["hssr"]["intervals_per_level"], c["hssr"]["intervals_per_level"], "hssr.intervals_per_level");
        same(g["hssr"]["iterations_per_ray_by_level"], c["hssr"]["iterations_per_ray_by_level"], "hssr.iterations_per_ray_by_level");
      }
    }
  // A fixed pool that the view overflows: detected on the device, reported with the exact count.
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + kDefault + " --width 160 --height 96 --quiet --effect shade -o " + (dir / "all.png")));
  const uint64_t total = readJson(dir / "all.json")["fragments"]["total"].get<uint64_t>();
  std::string err;
  EXPECT_EQ(test::runCli("render " + kDefault + " --width 160 --height 96 --quiet --effect shade --device gpu --pool 1000 -o " + (dir / "p.png"), &err), 2);
  EXPECT_NE(err.find(std::to_string(total) + " fragments generated"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(dir / "p.png"));
  // A pool that grows: the same answers, the frame run again.
  ASSERT_NO_FATAL_FAILURE(expectRuns("render " + kDefault + " --width 160 --height 96 --quiet --effect shade --device gpu -o " + (dir / "g.png")));
  EXPECT_EQ(readJson(dir / "g.json")["fragments"]["total"], total);
  // Checked ray by ray on the host: the layers are read back, the frame is not resident.
  ASSERT_NO_FATAL_FAILURE(
      expectRuns("render " + kDefault + " --width 96 --height 64 --quiet --device gpu --check-oracle -o " + (dir / "o.png")));
  EXPECT_EQ(readJson(dir / "o.json")["gpu"]["resident"], false);
}

TEST(CliGpu, CompareReportsTheAgreementOfTheSameRaysOnBothDevices) {
  if (!gpuBuilt()) GTEST_SKIP() << "built without the GPU back end";
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(expectRuns("compare " + kDefault + " --width 160 --height 90 --quiet --device gpu --tracers ssr,ssr-layers,hssr,quadtree,ldc,grid,hybrid,embree -o " +
                                     (dir / "c")));
  const auto j = readJson(dir / "c/compare.json");
  EXPECT_EQ(j["device"], "gpu");
  for (const char* t : {"ssr", "ssr-layers", "hssr", "quadtree", "ldc", "grid", "hybrid"}) {
    EXPECT_EQ(j["compare"][t]["gpu_agreement"].get<double>(), 1.0) << t;
    EXPECT_GT(j["compare"][t]["gpu_trace_ms"].get<double>(), 0.0) << t;
    // (the hybrid's geometric half is the grid on the GPU, Embree on the CPU: other counts)
    if (std::string(t) != "hybrid") {
      EXPECT_EQ(j["compare"][t]["gpu_iterations_mean"], j["compare"][t]["iterations_mean"]) << t;
    }
  }
  EXPECT_FALSE(j["compare"]["embree"].contains("gpu_agreement"));  // no GPU version
  // Any-hit rays (AO) are asked as any-hit queries on the GPU too: a geometric tracer's any-hit
  // answer names no pixel, its closest-hit answer does.
  ASSERT_NO_FATAL_FAILURE(expectRuns("compare " + kDefault + " --width 160 --height 90 --quiet --device gpu --effect ao --ao-samples 2 "
                                     "--tracers grid,ldc,hssr -o " + (dir / "ao")));
  const auto ao = readJson(dir / "ao/compare.json");
  for (const char* t : {"grid", "ldc", "hssr"}) {
    EXPECT_EQ(ao["compare"][t]["gpu_agreement"].get<double>(), 1.0) << t;
    EXPECT_EQ(ao["compare"][t]["gpu_iterations_mean"], ao["compare"][t]["iterations_mean"]) << t;
  }
}

TEST(CliGpu, LayersCapturedOnTheGpuAreVerifiedAgainstEmbreeAndTheCpu) {
  if (!gpuBuilt()) GTEST_SKIP() << "built without the GPU back end";
  test::TempDir dir;
  for (const std::string capture : {"lists", "peel"}) {
    ASSERT_NO_FATAL_FAILURE(expectRuns("layers " + kDefault + " --width 200 --height 120 --quiet --device gpu --verify --capture " + capture +
                                       " -o " + (dir / capture)));
    const auto j = readJson(dir / (capture + "/layers.json"));
    EXPECT_EQ(j["device"], "gpu");
    EXPECT_EQ(j["capture_pipeline"], "gpu-" + capture);
    EXPECT_GE(j["verify"]["match_fraction"].get<double>(), 0.999) << capture;
    EXPECT_GE(j["verify"]["gpu_vs_cpu"]["match_fraction"].get<double>(), 0.9999) << capture;
    EXPECT_EQ(j["fragments"]["geometry_passes"], capture == "peel" ? 8 : 1);
    EXPECT_TRUE(fs::exists(dir / (capture + "/layer0_albedo.png")));
  }
}

// A scene whose textures exceed the GPU's largest storage buffer (128 MiB on llvmpipe) renders
// with --device gpu all the same: the CPU captures, one warning line says why.
TEST(CliGpu, RenderCapturesOnTheCpuWhenTheTexturesExceedTheGpusBuffers) {
  if (!gpuBuilt()) GTEST_SKIP() << "built without the GPU back end";
  test::TempDir dir;
  {
    // An uncompressed 8192×4096 TGA: 128 MiB of texels before its mip levels.
    const int W = 8192, H = 4096;
    std::ofstream tga(dir / "big.tga", std::ios::binary);
    const unsigned char header[18] = {0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, W & 255, W >> 8, H & 255, H >> 8, 24, 0};
    tga.write(reinterpret_cast<const char*>(header), sizeof header);
    const std::string row(size_t(W) * 3, char(160));
    for (int y = 0; y < H; ++y) tga.write(row.data(), std::streamsize(row.size()));
  }
  std::ofstream(dir / "quad.mtl") << "newmtl big\nKd 1 1 1\nmap_Kd big.tga\n";
  std::ofstream(dir / "quad.obj") << "mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl big\n"
                                     "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
  std::string err;
  ASSERT_EQ(test::runCli("render " + (dir / "quad.obj") + " --device gpu --width 64 --height 48 --effect shade --quiet -o " + (dir / "q.png"), &err), 0)
      << err;
  EXPECT_NE(err.find("largest storage buffer"), std::string::npos) << err;
  EXPECT_NE(err.find("capturing on the CPU"), std::string::npos) << err;
  const auto j = readJson(dir / "q.json");
  EXPECT_EQ(j["device"], "gpu");
  EXPECT_EQ(j["capture_pipeline"].get<std::string>().rfind("gpu-", 0), std::string::npos) << j["capture_pipeline"];
  EXPECT_GT(j["fragments"]["total"].get<double>(), 64.0 * 48.0 / 4.0);
}

// bench --experiment frame: frames along an orbit, each counted, on both devices.
TEST(CliGpu, BenchFrameCountsEveryFrameOnBothDevices) {
  test::TempDir dir;
  for (const std::string device : {"cpu", "gpu"}) {
    if (device == "gpu" && !gpuBuilt()) continue;
    SCOPED_TRACE(device);
    const std::string out = dir / device;
    ASSERT_NO_FATAL_FAILURE(expectRuns("bench " + kDefault + " --experiment frame --frames 3 --width 96 --height 64 --quiet --images --device " +
                                       device + " -o " + out));
    const auto j = readJson(out + "/frame.json");
    ASSERT_EQ(j["frames"].size(), 3u);
    for (const char* k : {"frames", "wall_ms", "gpu_ms", "upload_bytes", "download_bytes", "host_waits", "program_links", "buffer_allocations",
                          "dispatches", "draws"})
      EXPECT_TRUE(j["summary"].contains(k)) << k;
    EXPECT_EQ(j["summary"]["frames"], 3);
    for (const auto& f : j["frames"]) EXPECT_GT(f["rays"].get<double>(), 96.0 * 64.0 / 4.0);
    if (device == "gpu") {
      EXPECT_EQ(j["summary"]["program_links"], 0);
      EXPECT_EQ(j["summary"]["buffer_allocations"], 0);
      EXPECT_EQ(j["summary"]["host_waits"], 1);
      EXPECT_GT(j["frames"][0]["program_links"].get<int>(), 0);
    } else {
      EXPECT_EQ(j["summary"]["gpu_ms"], 0.0);
    }
    for (const char* f : {"frame.csv", "frame_0000.png", "frame_0002.png"}) EXPECT_TRUE(fs::exists(out + "/" + f)) << f;
  }
  // A tracer without a resident GPU frame, refused by name before anything is written.
  if (gpuBuilt()) {
    std::string err;
    EXPECT_EQ(test::runCli("bench " + kDefault + " --experiment frame --device gpu --tracer hybrid --quiet -o " + (dir / "bad"), &err), 2);
    EXPECT_NE(err.find("--tracer hybrid"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(dir / "bad"));
  }
}

TEST(CliGpu, BenchReportsEveryStageOnBothDevicesAndListsAgainstPeeling) {
  if (!gpuBuilt()) GTEST_SKIP() << "built without the GPU back end";
  test::TempDir dir;
  for (const std::string device : {"cpu", "gpu"}) {
    ASSERT_NO_FATAL_FAILURE(expectRuns("bench " + kDefault + " --experiment stages --repeat 1 --width 160 --height 90 --quiet --device " + device +
                                       " -o " + (dir / device)));
    const auto j = readJson(dir / (device + "/stages.json"));
    EXPECT_EQ(j["device"], device);
    ASSERT_EQ(j["rows"].size(), device == "gpu" ? 10u : 9u);  // the GPU adds HSSR with persistent threads
    std::map<std::string, double> iterations;
    for (const auto& row : j["rows"]) {
      EXPECT_GT(row["trace_ms"].get<double>(), 0.0) << row;
      EXPECT_GT(row["memory_bytes"].get<double>(), 0.0) << row;
      // The default effect (reflection) runs on the device with every GPU tracer but the
      // hybrid, whose answers are shaded on the CPU.
      const std::string name = row["tracer"];
      const bool deviceEffect = device == "gpu" && name != "hybrid" && name != "embree";
      EXPECT_EQ(row["shade_device"], deviceEffect ? "gpu" : "cpu") << row;
      EXPECT_EQ(row["effect_bytes"].get<double>() > 0.0, deviceEffect) << row;
      iterations[row["tracer"].get<std::string>() + row["stride"].dump()] = row["iterations_mean"].get<double>();
    }
    EXPECT_LT(iterations["hssr1.0"], iterations["ssr-layers1.0"]) << device << ": the hierarchy skips empty space";
  }
  // The same rays, the same answers: the GPU's counters equal the CPU's.
  const auto c = readJson(dir / "cpu/stages.json")["rows"], g = readJson(dir / "gpu/stages.json")["rows"];
  // (the hybrid's geometric half: Embree on the CPU, the grid on the GPU)
  for (size_t i = 0; i < c.size(); ++i) {
    if (c[i]["tracer"] != "hybrid") {
      EXPECT_EQ(c[i]["iterations_mean"], g[i]["iterations_mean"]) << c[i]["tracer"];
    }
  }
  EXPECT_EQ(g[5]["tracer"], "quadtree");
  EXPECT_EQ(g[6]["tracer"], "ldc");
  EXPECT_EQ(g[7]["tracer"], "grid");
  EXPECT_EQ(g[8]["tracer"], "hybrid");
  EXPECT_EQ(g[9]["persistent"], true);
  EXPECT_EQ(g[9]["iterations_mean"], g[4]["iterations_mean"]);  // another schedule, the same rays and steps
  ASSERT_NO_FATAL_FAILURE(expectRuns("bench " + kDefault + " --experiment peel --repeat 1 --width 96 --height 54 --quiet --device gpu -o " + (dir / "peel")));
  const auto p = readJson(dir / "peel/peel.json")["rows"];
  ASSERT_EQ(p.size(), 8u);
  EXPECT_LT(p[0]["peel_bytes"].get<double>(), p[7]["peel_bytes"].get<double>());  // peeling's memory grows with k
}

TEST(CliGpu, GeobenchWalksTheGridOnTheGpuAsOnTheCpu) {
  if (!gpuBuilt()) GTEST_SKIP() << "built without the GPU back end";
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(expectRuns("geobench " + kDefault + " --device gpu --width 96 --height 54 --repeat 1 --quiet -o " + (dir / "g")));
  const auto j = readJson(dir / "g/geobench.json")["geobench"];
  const auto& g = j["grid_gpu"];
  for (const char* set : {"primary", "ao", "diffuse"}) {
    EXPECT_EQ(g[std::string("agreement_cpu_grid_") + set].get<double>(), 1.0) << set;  // the CPU grid's answers
    EXPECT_GT(g[std::string("mrays_") + set].get<double>(), 0.0) << set;
  }
  EXPECT_EQ(g["build"], "cpu");
  // The grid built on the GPU, merged and expanded: the CPU build's cells, references and moved
  // faces, and its answers (Embree's, as the CPU grid's are).
  const auto& b = j["grid_gpu_build"];
  EXPECT_EQ(b["build"], "gpu");
  EXPECT_EQ(b["cells"], b["cpu_twin"]["cells"]);
  EXPECT_EQ(b["references"], b["cpu_twin"]["references"]);
  EXPECT_TRUE(b["cpu_twin"]["same_cells"].get<bool>());
  EXPECT_LT(b["cells"].get<double>(), b["cells_initial"].get<double>()) << "nothing merged on the GPU";
  EXPECT_GT(b["expanded_faces"].get<double>(), 0.0);
  EXPECT_GT(b["build_ms"].get<double>(), 0.0);
  for (const char* set : {"primary", "ao", "diffuse"}) {
    EXPECT_EQ(b[std::string("agreement_") + set].get<double>(), j["grid"][std::string("agreement_") + set].get<double>()) << set;
    EXPECT_EQ(b[std::string("agreement_cpu_grid_") + set].get<double>(), 1.0) << set;
    EXPECT_GT(b[std::string("mrays_") + set].get<double>(), 0.0) << set;
  }
}

TEST(CliGpu, NoDeviceOrNoGpuVersionIsOneLineStatusTwo) {
  test::TempDir dir;
  expectRejected({"render " + kDefault + " --tracer embree --device gpu", "embree"}, dir);
  expectRejected({"compare " + kDefault + " --tracers embree --device gpu", "--device gpu"}, dir);
  expectRejected({"render " + kDefault + " --device tpu", "--device"}, dir);
  expectRejected({"bench " + kDefault + " --experiment tau --device gpu", "--device gpu"}, dir);
  expectRejected({"layers " + kDefault + " --capture peel --device gpu --adaptive-thickness", "--adaptive-thickness"}, dir);
  // A machine whose EGL has no driver: the device is asked for before the scene is loaded.
  setenv("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent.json", 1);
  expectRejected({"render " + kDefault + " --tracer hssr --device gpu", "--device gpu"}, dir);
  unsetenv("__EGL_VENDOR_LIBRARY_FILENAMES");
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// An alpha-tested grate through the whole CLI: the capture keeps exactly Embree's surfaces
// (rays pass through the holes and stop on the bars), compare's tracers answer as the
// references do, --textures off makes the grate solid, and a texture over the size limit is
// refused with one line.
TEST(CliTextures, CutOutGrateIsExactInLayersAndCompare) {
  test::TempDir dir;
  const std::string scene = test::writeGrateObj(dir);
  // The rasterizer snaps vertices to 1/256 pixel, so a pixel centre within that of a silhouette
  // may disagree with Embree (verify's tolerance in other tests). This view has no such pixel:
  // it is exact with the grate solid (--textures off), and the alpha test must keep it exact.
  const std::string view = " --eye 0.35,0.45,1.5 --target 0,0.2,-3 --fov 55 --width 160 --height 120 --quiet";
  ASSERT_NO_FATAL_FAILURE(expectRuns("layers " + scene + view + " --verify -o " + (dir / "on") + " --stats " + (dir / "on.json")));
  ASSERT_NO_FATAL_FAILURE(
      expectRuns("layers " + scene + view + " --verify --textures off -o " + (dir / "off") + " --stats " + (dir / "off.json")));
  const auto on = readJson(dir / "on.json"), off = readJson(dir / "off.json");
  EXPECT_EQ(on["verify"]["match_fraction"].get<double>(), 1.0);
  EXPECT_EQ(off["verify"]["match_fraction"].get<double>(), 1.0);
  // The holes: fewer fragments with the alpha test than with the solid grate.
  const double holes = off["fragments"]["total"].get<double>() - on["fragments"]["total"].get<double>();
  EXPECT_GT(holes, 160.0 * 120.0 / 20.0);
  EXPECT_LT(holes, off["fragments"]["total"].get<double>() / 2.0);
  ASSERT_NO_FATAL_FAILURE(expectRuns("compare " + scene + view + " --tracers hssr,grid,hybrid --check-exhaustive --check-oracle -o " +
                                     (dir / "c")));
  const auto c = readJson(dir / "c/compare.json")["compare"];
  EXPECT_EQ(c["hssr"]["exhaustive_mismatch"], 0);
  EXPECT_EQ(c["hssr"]["oracle_mismatch"], 0);
  for (const char* t : {"grid", "hybrid"})
    EXPECT_EQ(c[t]["correct_hit"].get<double>() + c[t]["correct_miss"].get<double>(), 1.0) << t;
  // bench measures the texturing against --textures off on the same view.
  ASSERT_NO_FATAL_FAILURE(expectRuns("bench " + scene + view + " --experiment textures --repeat 1 -o " + (dir / "b")));
  const auto rows = readJson(dir / "b/textures.json")["rows"];
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0]["textures"], "on");
  EXPECT_EQ(rows[0]["cut_out_materials"], 1);
  EXPECT_EQ(rows[1]["textured_materials"], 0);
  EXPECT_LT(rows[0]["fragments"].get<double>(), rows[1]["fragments"].get<double>());
  EXPECT_EQ(rows[1]["capture_vs_off"].get<double>(), 1.0);
  EXPECT_GT(rows[0]["reference_trace_ms"].get<double>(), 0.0);
  test::TempDir big, out1, out2;
  expectRejected({"layers " + test::writeGrateObj(big, 16385) + view, "16385"}, out1);
  expectRejected({"layers " + scene + view + " --textures maybe", "--textures"}, out2);
}

}  // namespace
}  // namespace lt
