// Image files: write-then-read round trips, atomic writes, bad paths.
#include <filesystem>

#include "layertrace/util/error.h"
#include "layertrace/util/image.h"
#include "test_util.h"

namespace lt {
namespace {

Image gradient(int w, int h, int c) {
  Image im(w, h, c);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int k = 0; k < c; ++k) im.at(x, y)[k] = float(x + 3 * y + 7 * k) / float(w + 3 * h + 7 * c);
  return im;
}

TEST(Image, ExrRoundTripIsExact) {
  test::TempDir dir;
  for (int c : {1, 3}) {
    Image im = gradient(37, 21, c);
    im.at(3, 4)[0] = 1234.5f;  // HDR survives
    writeImage(dir / "a.exr", im);
    const Image back = readImage(dir / "a.exr");
    ASSERT_EQ(back.width, 37);
    ASSERT_EQ(back.channels, c);
    EXPECT_EQ(back.data, im.data);
  }
}

TEST(Image, PngRoundTripWithinQuantisation) {
  test::TempDir dir;
  const Image im = gradient(40, 30, 3);
  for (bool srgb : {true, false}) {
    writeImage(dir / "a.png", im, srgb);
    const Image back = readImage(dir / "a.png", srgb);
    ASSERT_EQ(back.width, 40);
    ASSERT_EQ(back.height, 30);
    for (size_t i = 0; i < im.data.size(); ++i)
      ASSERT_NEAR(back.data[i], im.data[i], srgb ? 0.5f / 255.0f * 13.0f * 0.25f + 0.004f : 0.5f / 255.0f + 1e-6f);
  }
}

TEST(Image, BadPathsAndExtensionsLeaveNothingBehind) {
  test::TempDir dir;
  const Image im = gradient(4, 4, 3);
  EXPECT_THROW(writeImage(dir / "a.bmp", im), InputError);
  EXPECT_THROW(writeImage(dir / "missing/dir/a.png", im), InputError);
  EXPECT_THROW(writeImage(dir / "missing/dir/a.exr", im), InputError);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path));
}

}  // namespace
}  // namespace lt
