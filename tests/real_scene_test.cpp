// The fetched real scenes (scripts/fetch-scenes.sh; `make test` fetches them first).
#include <cstring>
#include <map>
#include <set>
#include <filesystem>

#include <tbb/global_control.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/eval/verify_layers.h"
#include "layertrace/geometry/embree_scene.h"
#include "layertrace/util/error.h"
#include "test_util.h"

namespace lt {
namespace {

struct VerifyCase {
  const char* scene;
  const char* camera;
};

class RealSceneVerify : public ::testing::TestWithParam<VerifyCase> {};

// The fragment lists match Embree's all-hit primary rays on ≥ 99.9 % of pixels at
// 1280×720. The residue is pixels whose centre lies exactly on a shared edge or vertex, where
// Embree reports both or neither neighbour and the top-left rule reports exactly one, and
// near-grazing triangles whose coverage flips within float precision.
TEST_P(RealSceneVerify, FragmentListsMatchEmbreeAllHits) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  FrameOptions o = test::realSceneOptions(GetParam().scene, GetParam().camera);
  o.captureLists = true;
  const Frame frame = buildFrame(o);
  EXPECT_EQ(frame.lists.lost(), 0u);
  const EmbreeScene embree(frame.scene);
  const VerifyResult v = verifyLayers(frame.lists, frame.camera, embree);
  EXPECT_EQ(v.pixels, 1280u * 720u);
  EXPECT_GE(v.matchFraction(), 0.999) << "fewer " << v.fewerFragments << " more " << v.moreFragments << " depth " << v.depthMismatch;
}

// On real views the tile-local capture (the default pipeline) gives the reference
// pipeline's k-layer arrays and depth complexity bit for bit, with 1 and 2 threads, and with
// lists the same fragments in every pixel's list in the same order.
TEST_P(RealSceneVerify, TileLocalCaptureEqualsReferencePipeline) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  FrameOptions o = test::realSceneOptions(GetParam().scene, GetParam().camera);
  o.referenceCapture = true;
  Frame f = buildFrame(o);
  ASSERT_EQ(f.capturePipeline, "reference");
  const LayerArrays want = f.layers;
  const FragmentLists wantLists = f.lists;
  o.referenceCapture = false;
  for (int threads : {1, 2})
    for (bool lists : {false, true}) {
      tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(threads));
      o.captureLists = lists;
      rasterizeFrame(o, f);  // the same scene and camera, captured again tile by tile into reused memory
      const std::string what = cat(threads, " threads, ", f.capturePipeline);
      ASSERT_EQ(f.capturePipeline, lists ? "tiles+lists" : "tiles");
      EXPECT_EQ(f.lists.generated, wantLists.generated) << what;
      EXPECT_TRUE(f.lists.complexity == wantLists.complexity) << what;
      EXPECT_TRUE(f.layers.count == want.count && f.layers.triangle == want.triangle) << what;
      ASSERT_EQ(f.layers.slots.size(), want.slots.size());
      EXPECT_EQ(std::memcmp(f.layers.slots.data(), want.slots.data(), want.slots.size() * sizeof(FragmentNode)), 0) << what;
      if (!lists) continue;
      ASSERT_EQ(f.lists.nodes.size(), wantLists.generated) << "exact-size storage";
      EXPECT_TRUE(test::sameListContents(f.lists, wantLists)) << what;
    }
}

INSTANTIATE_TEST_SUITE_P(Scenes, RealSceneVerify,
                         ::testing::Values(VerifyCase{"fzk-haus.json", "interior"}, VerifyCase{"am-thornish.json", "hall"},
                                           VerifyCase{"engine.json", "interior"}),
                         [](const auto& p) { return test::sceneCaseName(p.param.scene); });

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// An OpenArena map through the game's archives: its shaders resolve to the game's images (all
// but a few), the captured fragments show the textures (many colours per material), and
// --lightmaps adds the map's lightmaps, which change the colours and nothing else.
TEST(RealSceneTextures, OpenArenaMapLoadsWithItsGameTexturesAndLightmaps) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  FrameOptions o = test::realSceneOptions("am-thornish.json", "hall");
  o.width = 320, o.height = 180;
  const Frame plain = buildFrame(o);
  size_t textured = 0, lit = 0;
  for (const Material& m : plain.scene.materials) textured += m.baseTexture >= 0, lit += m.lightmap >= 0;
  EXPECT_GE(textured, plain.scene.materials.size() * 9 / 10) << "shaders resolved to images";
  EXPECT_EQ(lit, 0u) << "lightmaps only with --lightmaps";
  std::map<uint32_t, std::set<uint32_t>> colours;  // per material, the fragments' distinct colours
  for (size_t p = 0; p < plain.layers.count.size(); ++p)
    if (plain.layers.count[p]) colours[plain.scene.triMaterial[plain.layers.triangle[p * size_t(plain.layers.k)]]].insert(plain.layers.slots[p * size_t(plain.layers.k)].albedoSpec);
  size_t varied = 0;
  for (const auto& [m, c] : colours) varied += c.size() > 8;
  EXPECT_GE(varied, colours.size() / 2) << "textures vary across surfaces";
  o.lightmaps = true;
  const Frame lightmapped = buildFrame(o);
  lit = 0;
  for (const Material& m : lightmapped.scene.materials) lit += m.lightmap >= 0;
  EXPECT_GE(lit, lightmapped.scene.materials.size() / 2);
  EXPECT_EQ(lightmapped.layers.triangle, plain.layers.triangle) << "the same geometry";
  size_t changed = 0;
  for (size_t s = 0; s < plain.layers.slots.size(); ++s) changed += plain.layers.slots[s].albedoSpec != lightmapped.layers.slots[s].albedoSpec;
  EXPECT_GT(changed, plain.layers.slots.size() / 4);
}

}  // namespace
}  // namespace lt
