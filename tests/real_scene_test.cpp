// The fetched real scenes (scripts/fetch-scenes.sh; `make test` fetches them first).
#include <filesystem>

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
  const FrameOptions o = test::realSceneOptions(GetParam().scene, GetParam().camera);
  const Frame frame = buildFrame(o);
  EXPECT_EQ(frame.lists.lost(), 0u);
  const EmbreeScene embree(frame.scene);
  const VerifyResult v = verifyLayers(frame.lists, frame.camera, embree);
  EXPECT_EQ(v.pixels, 1280u * 720u);
  EXPECT_GE(v.matchFraction(), 0.999) << "fewer " << v.fewerFragments << " more " << v.moreFragments << " depth " << v.depthMismatch;
}

INSTANTIATE_TEST_SUITE_P(Scenes, RealSceneVerify,
                         ::testing::Values(VerifyCase{"fzk-haus.json", "interior"}, VerifyCase{"am-thornish.json", "hall"},
                                           VerifyCase{"engine.json", "interior"}),
                         [](const auto& p) { return test::sceneCaseName(p.param.scene); });

}  // namespace
}  // namespace lt
