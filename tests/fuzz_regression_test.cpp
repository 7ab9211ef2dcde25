// Inputs the fuzzers of fuzz/ found, replayed through the same entry points (tests/fuzz_regressions/
// TARGET/): each must end as a scene or as an input error naming the input — never as a crash, a
// hang or an internal error.
#include <filesystem>
#include <fstream>
#include <iterator>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"
#include "test_util.h"

namespace lt {
namespace {

std::string slurpFile(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::filesystem::path> regressions(const std::string& target) {
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(test::sourceDir() + "/tests/fuzz_regressions/" + target)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

// fuzz_json_scene: a number beyond double ("0.11e392") made nlohmann throw out_of_range, which
// escaped as an internal error (status 1) instead of bad input.
TEST(FuzzRegression, JsonScenesEndAsScenesOrInputErrors) {
  const auto files = regressions("json_scene");
  ASSERT_FALSE(files.empty());
  for (const auto& f : files) {
    SCOPED_TRACE(f.filename().string());
    try {
      parseJsonScene(slurpFile(f), "/nonexistent-layertrace-fuzz", f.filename().string());
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(f.filename().string()), std::string::npos) << e.what();
    }
  }
}

// fuzz_model: assimp's PLY reader loops forever on this header; the import watchdog stops it
// with one line and status 2.
TEST(FuzzRegressionDeathTest, AnImporterThatNeverFinishesIsStopped) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const std::string bytes = slurpFile(test::sourceDir() + "/tests/fuzz_regressions/model/ply-header-loop.bin");
  ASSERT_GT(bytes.size(), 1u);
  ASSERT_EQ(bytes[0], 1) << "format index 1 of fuzz_model.cpp: ply";
  EXPECT_EXIT(
      {
        setModelImportTimeout(2);
        loadModelFromMemory(bytes.data() + 1, bytes.size() - 1, "ply", "loop.ply");
      },
      ::testing::ExitedWithCode(2), "scene loop.ply: the model importer did not finish in time");
}

}  // namespace
}  // namespace lt
