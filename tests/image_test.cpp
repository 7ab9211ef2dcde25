// Image files: write-then-read round trips, atomic writes, bad paths.
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <vector>

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

// The thresholds the GPU encodes with give encode8's sRGB code of every value: at and around
// each threshold, over [0, 1] densely, and for values outside it (negative, above 1, infinite,
// NaN).
TEST(Image, Srgb8ThresholdsGiveTheCodesOfEncode8) {
  const std::array<float, 255> t = srgb8Thresholds();
  // the rule shaders/frame_picture.comp applies: the number of thresholds at or below the value
  const auto code = [&](float v) { return uint8_t(std::count_if(t.begin(), t.end(), [v](float x) { return x <= v; })); };
  std::vector<float> values = {-1.0f, -0.0f, 0.0f, 1.0f, 1.5f, 1e30f, std::numeric_limits<float>::infinity(),
                               -std::numeric_limits<float>::infinity(), std::numeric_limits<float>::denorm_min()};
  for (float v : t) values.insert(values.end(), {v, std::nextafter(v, 0.0f), std::nextafter(v, 2.0f)});
  for (int i = 0; i <= 1 << 16; ++i) values.push_back(float(i) / float(1 << 16));
  size_t differ = 0;
  for (float v : values) differ += code(v) != encodeChannel8(v, true);
  EXPECT_EQ(differ, 0u);
  EXPECT_TRUE(std::is_sorted(t.begin(), t.end()));
  EXPECT_EQ(code(std::numeric_limits<float>::quiet_NaN()), 0);  // no threshold is at or below NaN
}

}  // namespace
}  // namespace lt
