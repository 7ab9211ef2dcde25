// The fetched real scenes (scripts/fetch-scenes.sh; `make test` fetches them first).
#include <cstring>
#include <filesystem>

#include <tbb/global_control.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/eval/verify_layers.h"
#include "layertrace/geometry/embree_scene.h"
#include "test_util.h"

namespace lt {
namespace {

struct VerifyCase {
  const char* scene;
  const char* camera;
};

class RealSceneVerify : public ::testing::TestWithParam<VerifyCase> {};

// Issue 2 §7: the fragment lists match Embree's all-hit primary rays on ≥ 99.9 % of pixels at
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

// Issue 13 §6: on real views the tile-local capture (the default pipeline) gives the list
// pipeline's k-layer arrays and depth complexity bit for bit, with 1 and 2 threads.
TEST_P(RealSceneVerify, TileLocalCaptureEqualsListPipeline) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  FrameOptions o = test::realSceneOptions(GetParam().scene, GetParam().camera);
  o.captureLists = true;
  Frame f = buildFrame(o);
  ASSERT_TRUE(f.listsCaptured());
  const LayerArrays want = f.layers;
  const std::vector<uint32_t> wantComplexity = f.lists.complexity;
  const uint64_t wantGenerated = f.lists.generated;
  o.captureLists = false;
  for (int threads : {1, 2}) {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(threads));
    rasterizeFrame(o, f);  // the same scene and camera, captured again tile by tile into reused memory
    ASSERT_FALSE(f.listsCaptured());
    EXPECT_EQ(f.lists.generated, wantGenerated);
    EXPECT_TRUE(f.lists.complexity == wantComplexity) << threads << " threads";
    EXPECT_TRUE(f.layers.count == want.count && f.layers.triangle == want.triangle) << threads << " threads";
    ASSERT_EQ(f.layers.slots.size(), want.slots.size());
    EXPECT_EQ(std::memcmp(f.layers.slots.data(), want.slots.data(), want.slots.size() * sizeof(FragmentNode)), 0) << threads << " threads";
  }
}

INSTANTIATE_TEST_SUITE_P(Scenes, RealSceneVerify,
                         ::testing::Values(VerifyCase{"fzk-haus.json", "interior"}, VerifyCase{"am-thornish.json", "hall"},
                                           VerifyCase{"engine.json", "interior"}),
                         [](const auto& p) { return test::sceneCaseName(p.param.scene); });

}  // namespace
}  // namespace lt
