// Quake 3's texture lookup over .pk3 archives (scene/quake3_textures.h): small archives written
// here, each test checking the bytes of the image a shader name finds.
#include <fstream>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "layertrace/scene/quake3_textures.h"
#include "test_util.h"

namespace lt {
namespace {

using Entries = std::vector<std::pair<std::string, std::string>>;

/// Writes a .pk3 of stored entries into `dir`; returns its path.
std::string writePk3(const test::TempDir& dir, const std::string& name, const Entries& entries) {
  const std::string path = dir / name;
  std::ofstream(path, std::ios::binary) << test::storedZip(entries);
  return path;
}

/// The bytes `find` returns for `shader`, as a string ("" when nothing is found).
std::string found(Quake3Textures& textures, const std::string& shader) {
  const std::optional<Quake3Textures::Image> image = textures.find(shader);
  return image ? std::string(image->bytes.begin(), image->bytes.end()) : std::string();
}

TEST(Quake3Textures, LaterArchiveWins) {
  test::TempDir dir;
  const std::string early = writePk3(dir, "pak0.pk3", {{"textures/base/wall.tga", "early wall"}, {"textures/base/floor.jpg", "floor"}});
  const std::string late = writePk3(dir, "pak1.pk3", {{"textures/base/wall.tga", "late wall"}});
  Quake3Textures textures({early, late});
  EXPECT_EQ(found(textures, "textures/base/wall"), "late wall");
  EXPECT_EQ(found(textures, "textures/base/floor"), "floor");  // only in the earlier archive
  const std::optional<Quake3Textures::Image> image = textures.find("textures/base/wall");
  ASSERT_TRUE(image);
  EXPECT_EQ(image->name, "textures/base/wall.tga");
  EXPECT_EQ(image->archive, late);
  Quake3Textures reversed({late, early});
  EXPECT_EQ(found(reversed, "textures/base/wall"), "early wall");
  EXPECT_EQ(textures.archiveCount(), 2u);
  EXPECT_TRUE(textures.warnings().empty());
}

TEST(Quake3Textures, ShaderScriptsFirstStageImageSkippingLightmaps) {
  test::TempDir dir;
  const std::string script = R"(// a comment { not a brace that counts
textures/base/glow
{
	qer_editorimage textures/base/editor.tga
	surfaceparm nomarks
	{
		map $lightmap   // no image: the next stage's is the shader's
		rgbGen identity
	}
	/* { map textures/base/commented.tga } */
	{
		clampMap textures/base/glow_base.jpg
		blendFunc filter
	}
	{
		map textures/base/glow_blend.tga
	}
}
textures/base/white
{
	{
		map $whiteimage
	}
}
)";
  const std::string pk3 = writePk3(dir, "pak0.pk3",
                                   {{"scripts/base.shader", script},
                                    {"textures/base/glow.tga", "image of the shader's name"},
                                    {"textures/base/editor.tga", "editor"},
                                    {"textures/base/commented.tga", "commented"},
                                    {"textures/base/glow_base.jpg", "glow base"},
                                    {"textures/base/glow_blend.tga", "glow blend"},
                                    {"textures/base/white.tga", "white's own"}});
  Quake3Textures textures({pk3});
  EXPECT_EQ(found(textures, "textures/base/glow"), "glow base");
  // A defined shader whose stages name no image: the image of its own name.
  EXPECT_EQ(found(textures, "textures/base/white"), "white's own");
  EXPECT_TRUE(textures.warnings().empty());
}

TEST(Quake3Textures, TgaThenJpgForAMissingExtension) {
  test::TempDir dir;
  const std::string pk3 = writePk3(dir, "pak0.pk3",
                                   {{"textures/a/both.jpg", "both jpg"},
                                    {"textures/a/both.tga", "both tga"},
                                    {"textures/a/onlyjpg.jpg", "only jpg"},
                                    {"textures/a/scripted.jpg", "scripted jpg"},
                                    {"textures/a/light_1.5.tga", "dotted"},
                                    {"scripts/a.shader", "textures/a/fromscript\n{\n{\nmap textures/a/scripted.tga\n}\n}\n"}});
  Quake3Textures textures({pk3});
  EXPECT_EQ(found(textures, "textures/a/both"), "both tga");
  EXPECT_EQ(found(textures, "textures/a/onlyjpg"), "only jpg");
  EXPECT_EQ(found(textures, "textures/a/onlyjpg.tga"), "only jpg");   // an image extension is replaced
  EXPECT_EQ(found(textures, "textures/a/both.jpg"), "both jpg");      // as given first
  EXPECT_EQ(found(textures, "textures/a/fromscript"), "scripted jpg"); // the script's .tga found as .jpg
  EXPECT_EQ(found(textures, "textures/a/light_1.5"), "dotted");       // ".5" is no image extension: .tga added
}

TEST(Quake3Textures, NamesCompareCaseInsensitivelyWithBackslashes) {
  test::TempDir dir;
  const std::string pk3 = writePk3(dir, "pak0.pk3",
                                   {{"Textures/Base_Wall/Concrete.TGA", "concrete"},
                                    {"textures\\gothic\\stone.jpg", "stone"},
                                    {"SCRIPTS/Gothic.SHADER", "Textures/Gothic/Block\n{\n{\nMAP textures/GOTHIC/Stone.tga\n}\n}\n"}});
  Quake3Textures textures({pk3});
  EXPECT_EQ(found(textures, "textures/base_wall/concrete"), "concrete");
  EXPECT_EQ(found(textures, "TEXTURES\\BASE_WALL\\CONCRETE"), "concrete");
  EXPECT_EQ(found(textures, "textures/gothic/block"), "stone");
}

TEST(Quake3Textures, AnimMapUsesItsFirstFrame) {
  test::TempDir dir;
  const std::string script = "textures/fx/flame\n{\n\t{\n\t\tanimMap 10 textures/fx/flame1.tga textures/fx/flame2.tga\n\t}\n}\n";
  const std::string pk3 = writePk3(dir, "pak0.pk3",
                                   {{"scripts/fx.shader", script},
                                    {"textures/fx/flame2.tga", "second frame"},
                                    {"textures/fx/flame1.tga", "first frame"}});
  Quake3Textures textures({pk3});
  EXPECT_EQ(found(textures, "textures/fx/flame"), "first frame");
}

// ioquake3 reads the latest archive's copy of a script, and of two scripts defining one shader
// keeps the definition it reads first: the earlier archive's.
TEST(Quake3Textures, ScriptDefinitionsFollowTheEngine) {
  test::TempDir dir;
  const std::string early = writePk3(dir, "pak0.pk3",
                                     {{"scripts/base.shader", "textures/s/replaced\n{\n{\nmap textures/s/old.tga\n}\n}\n"},
                                      {"scripts/other.shader", "textures/s/twice\n{\n{\nmap textures/s/first.tga\n}\n}\n"},
                                      {"textures/s/old.tga", "old"},
                                      {"textures/s/first.tga", "first"}});
  const std::string late = writePk3(dir, "pak1.pk3",
                                    {{"scripts/base.shader", "textures/s/replaced\n{\n{\nmap textures/s/new.tga\n}\n}\n"},
                                     {"scripts/patch.shader", "textures/s/twice\n{\n{\nmap textures/s/second.tga\n}\n}\n"},
                                     {"textures/s/new.tga", "new"},
                                     {"textures/s/second.tga", "second"}});
  Quake3Textures textures({early, late});
  EXPECT_EQ(found(textures, "textures/s/replaced"), "new");
  EXPECT_EQ(found(textures, "textures/s/twice"), "first");
}

TEST(Quake3Textures, MalformedArchiveIsSkippedWithAWarning) {
  test::TempDir dir;
  const std::string good = writePk3(dir, "pak0.pk3", {{"textures/a/wall.tga", "wall"}});
  const std::string bad = dir / "pak1.pk3";
  std::ofstream(bad, std::ios::binary) << "not a zip archive at all";
  std::string truncated = test::storedZip("textures/a/wall.tga", "truncated wall");
  truncated.resize(truncated.size() - 10);  // the end of the central directory cut off
  const std::string cut = dir / "pak2.pk3";
  std::ofstream(cut, std::ios::binary) << truncated;
  // A script with a missing brace is ignored whole, as the engine ignores it.
  const std::string script = writePk3(dir, "pak3.pk3",
                                      {{"scripts/broken.shader", "textures/a/wall\n{\n{\nmap textures/a/other.tga\n}\n"},
                                       {"textures/a/other.tga", "other"}});
  Quake3Textures textures({good, bad, cut, script});
  EXPECT_EQ(found(textures, "textures/a/wall"), "wall");
  const std::vector<std::string> warnings = textures.warnings();
  ASSERT_EQ(warnings.size(), 3u);
  EXPECT_NE(warnings[0].find("pak1.pk3"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("skipped"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[1].find("pak2.pk3"), std::string::npos) << warnings[1];
  EXPECT_NE(warnings[2].find("broken.shader"), std::string::npos) << warnings[2];
}

TEST(Quake3Textures, MissingNameGivesNothing) {
  test::TempDir dir;
  const std::string pk3 = writePk3(dir, "pak0.pk3",
                                   {{"textures/a/wall.tga", "wall"},
                                    {"scripts/a.shader", "textures/a/ghost\n{\n{\nmap textures/a/nowhere.tga\n}\n}\n"}});
  Quake3Textures textures({pk3});
  EXPECT_FALSE(textures.find("textures/a/door"));
  EXPECT_FALSE(textures.find("textures/a/ghost"));  // its image is in no archive, nor is one of its name
  EXPECT_FALSE(textures.find("noshader"));
  EXPECT_EQ(found(textures, "textures/a/wall"), "wall");  // (the archive was read)
  Quake3Textures none({});
  EXPECT_FALSE(none.find("textures/a/wall"));
}

TEST(Quake3Textures, ForMapSearchesTheGameFoldersByName) {
  test::TempDir dir;
  std::filesystem::create_directories(dir.path / "baseoa");
  const std::string map = writePk3(dir, "zz_map.pk3", {{"maps/zz_map.bsp", "IBSP"}, {"textures/m/wall.tga", "map's"}});
  writePk3(dir, "baseoa/pak0.pk3", {{"textures/m/wall.tga", "pak0's"}, {"textures/m/floor.tga", "pak0's floor"}});
  writePk3(dir, "baseoa/pak9.pk3", {{"textures/m/floor.tga", "pak9's floor"}});
  writePk3(dir, "baseoa/notes.txt", {});
  Quake3Textures textures = Quake3Textures::forMap(map);
  ASSERT_EQ(textures.archiveCount(), 3u);  // the map's own archive once
  EXPECT_EQ(std::filesystem::path(textures.archives()[0]).filename(), "pak0.pk3");
  EXPECT_EQ(std::filesystem::path(textures.archives()[2]).filename(), "zz_map.pk3");
  EXPECT_EQ(found(textures, "textures/m/wall"), "map's");  // "zz_map" sorts after "pak0"
  EXPECT_EQ(found(textures, "textures/m/floor"), "pak9's floor");
  // A map in a game folder's maps/ searches that folder's archives.
  std::filesystem::create_directories(dir.path / "baseoa/maps");
  std::ofstream(dir / "baseoa/maps/x.bsp", std::ios::binary) << "IBSP";
  Quake3Textures fromBsp = Quake3Textures::forMap(dir / "baseoa/maps/x.bsp");
  EXPECT_EQ(fromBsp.archiveCount(), 2u);
  EXPECT_EQ(found(fromBsp, "textures/m/wall"), "pak0's");
}

}  // namespace
}  // namespace lt
