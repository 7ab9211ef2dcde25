// Inputs the fuzzers of fuzz/ found, replayed through the same entry points (tests/fuzz_regressions/
// TARGET/): each must end as a scene or as an input error naming the input — never as a crash, a
// hang or an internal error.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <optional>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"
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

// fuzz_texture: a PNG whose zero-length read made stb_image call memcpy with a null pointer, which
// the sanitizer build's UBSan stopped at (stb's implementation is now spared that one check). The
// image decodes to nothing or to pixels; it never stops the process.
TEST(FuzzRegression, MalformedTexturesDecodeOrAreRefused) {
  const auto files = regressions("texture");
  ASSERT_FALSE(files.empty());
  for (const auto& f : files) {
    SCOPED_TRACE(f.filename().string());
    const std::string bytes = slurpFile(f);
    try {
      const std::optional<Rgba8Image> image = decodeRgba8(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), f.filename().string());
      if (image) {
        EXPECT_EQ(image->pixels.size(), size_t(image->width) * size_t(image->height) * 4);
      }
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

// Under the fuzzer (setModelImportCrashRecovery) the same importer becomes an InputError and the
// process goes on. (The stopped importer's memory is lost: the child ends without a leak check.)
TEST(FuzzRegressionDeathTest, WithCrashRecoveryAStoppedImporterIsAnInputError) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const std::string bytes = slurpFile(test::sourceDir() + "/tests/fuzz_regressions/model/ply-header-loop.bin");
  ASSERT_GT(bytes.size(), 1u);
  EXPECT_EXIT(
      {
        setModelImportTimeout(1);
        setModelImportCrashRecovery(true);
        try {
          loadModelFromMemory(bytes.data() + 1, bytes.size() - 1, "ply", "loop.ply");
        } catch (const InputError& e) {
          std::fprintf(stderr, "caught: %s\n", e.what());
          std::_Exit(3);
        }
        std::_Exit(4);
      },
      ::testing::ExitedWithCode(3), "caught: scene loop.ply: the model importer crashed on this file");
}

/// The message of the InputError `f` throws; a test failure (and "") when it throws none.
template <class F>
std::string inputErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return "";
}

/// The InputError message of a fuzz_model crash input of the OFF format (format index 3), loaded
/// under `name`.
std::string offRegressionError(const std::string& file, const std::string& name) {
  const std::string bytes = slurpFile(test::sourceDir() + "/tests/fuzz_regressions/model/" + file);
  EXPECT_EQ(bytes.size() > 1 ? bytes[0] % 20 : -1, 3) << "format index 3 of fuzz_model.cpp: off";
  return inputErrorOf([&] { loadModelFromMemory(bytes.data() + 1, bytes.size() - 1, "off", name); });
}

// fuzz_model: an OFF header counting 1.1·10³³ faces was refused with a message that converted
// the count to an integer (undefined behaviour, UBSan in the fuzz build); the count is now said
// as it was read.
TEST(FuzzRegression, AnOffCountBeyondIntegersIsRefusedByName) {
  const std::string what = offRegressionError("off-huge-count.bin", "huge.off");
  EXPECT_NE(what.find("scene huge.off: the OFF header declares 3 vertices and 1.11111e+33 faces"), std::string::npos) << what;
}

// fuzz_model: "OFF5555…5\n3 1 0" — the vertex count glued to the keyword and the face count on
// the next line — escaped the header check, and assimp reserved 45 GB for the vertices (ASan:
// out of memory; a Release build got std::bad_alloc). The counts are now read across lines.
TEST(FuzzRegression, AnOffCountGluedToTheKeywordIsChecked) {
  const std::string what = offRegressionError("off-count-after-keyword.bin", "glued.off");
  EXPECT_NE(what.find("scene glued.off: the OFF header declares 5.55556e+37 vertices and 3 faces"), std::string::npos) << what;
  // A well-formed header in any of these layouts still loads.
  for (const char* text : {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                           "OFF\n# comment\n3\n1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"}) {
    const std::string off = text;
    EXPECT_EQ(loadModelFromMemory(off.data(), off.size(), "off", "ok.off").triangleCount(), 1u) << off;
  }
}


void expectMentions(const std::string& message, std::initializer_list<const char*> needles) {
  for (const char* n : needles) EXPECT_NE(message.find(n), std::string::npos) << n << ": " << message;
}

// An archive that declares huge sizes (a zip bomb as .pk3) is refused before assimp
// inflates it; the limits are checked on the central directory alone.
TEST(FuzzRegression, ZipBombPk3IsRefusedBeforeImport) {
  test::TempDir dir;
  const std::string bomb = dir / "bomb.pk3", small = dir / "small.pk3";
  std::ofstream(bomb, std::ios::binary) << test::storedZip("maps/x.bsp", std::string(16, 'x'), 3u << 30);
  std::ofstream(small, std::ios::binary) << test::storedZip("maps/x.bsp", std::string(200, 'x'));
  expectMentions(inputErrorOf([&] { loadModel(bomb); }), {"zip bomb", "bomb.pk3"});
  EXPECT_NO_THROW(checkArchiveSizes(small, 200));
  EXPECT_THROW(checkArchiveSizes(small, 199), InputError);  // the total limit, exactly
}

// fuzz_pk3: assimp's Q3BSP importer followed a lump directory past the end of a truncated map
// (heap-use-after-free under ASan). The map is now checked before assimp reads it.
TEST(FuzzRegression, MalformedQuake3MapsAreRefusedBeforeImport) {
  const auto files = regressions("pk3");
  ASSERT_FALSE(files.empty());
  test::TempDir dir;
  for (const auto& f : files) {
    SCOPED_TRACE(f.filename().string());
    const std::string copy = dir / "map.pk3";
    std::ofstream(copy, std::ios::binary) << slurpFile(f);
    expectMentions(inputErrorOf([&] { loadModel(copy); }), {"malformed Quake 3 map", "map.pk3:maps/"});
  }
}

/// A one-triangle Quake 3 map (IBSP 46): one texture, three vertices, three mesh vertices, one
/// polygon face; the other lumps empty.
std::string tinyBsp() {
  std::string meshVerts, face;
  for (int v = 0; v < 3; ++v) test::appendLe32(meshVerts, uint32_t(v));
  for (int32_t x : {0, -1, 1, 0, 3, 0, 3, -1}) test::appendLe32(face, uint32_t(x));  // texture, effect, type 1, vertex 0+3, mesh vertex 0+3, lightmap
  face.resize(104, '\0');
  return test::quake3Map({{1, std::string(72, '\0')}, {10, std::string(3 * 44, '\0')}, {11, meshVerts}, {13, face}});
}

void setI32(std::string& s, size_t at, int32_t v) {
  for (int i = 0; i < 4; ++i) s[at + size_t(i)] = char((uint32_t(v) >> (8 * i)) & 0xFF);
}

// Every field the importer follows is checked; each single corruption is refused by name.
TEST(FuzzRegression, Quake3MapChecksCoverEveryIndexTheImporterFollows) {
  auto check = [](const std::string& b) { validateQuake3Bsp(reinterpret_cast<const unsigned char*>(b.data()), b.size(), "t.bsp"); };
  const std::string good = tinyBsp();
  try {
    check(good);
  } catch (const InputError& e) {
    FAIL() << e.what();
  }
  const size_t faceAt = good.size() - 104, meshAt = faceAt - 12;
  struct Corruption {
    size_t at;
    int32_t value;
    const char* message;
  };
  for (const Corruption c : {Corruption{4, 47, "version 47"}, Corruption{8 + 8 * 10, 1 << 30, "lump 10"},
                             Corruption{8 + 8 * 13 + 4, 100, "not a multiple"}, Corruption{faceAt, 1, "texture 1"},
                             Corruption{faceAt + 8, 7, "type 7"}, Corruption{faceAt + 16, 4, "vertices 0+4"},
                             Corruption{faceAt + 24, 4, "mesh vertices 0+4"}, Corruption{faceAt + 28, 0, "lightmap 0"},
                             Corruption{meshAt + 8, 3, "mesh vertex 2 is 3"}}) {
    std::string b = good;
    setI32(b, c.at, c.value);
    expectMentions(inputErrorOf([&] { check(b); }), {c.message});
  }
  EXPECT_THROW(check(good.substr(0, 100)), InputError);
}

}  // namespace
}  // namespace lt

