// Textures (scene/texture.h, scene/surface.h): the mip chain and the trilinear filter against
// direct arithmetic, and an alpha-tested checkerboard grate that every consumer of surfaces must
// see alike — the captures against Embree's all-hit reference, the grid against Embree, the
// geometric hits' shading against the captured fragments.
#include <algorithm>
#include <array>
#include <cstring>
#include <optional>
#include <string>
#include <bit>
#include <cmath>
#include <random>
#include <vector>

#include <glm/geometric.hpp>

#include "layertrace/eval/verify_layers.h"
#include "layertrace/geometry/embree_scene.h"
#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/grid/irregular_grid.h"
#include "layertrace/raster/capture.h"
#include "layertrace/raster/rasterizer.h"
#include "layertrace/scene/surface.h"
#include "layertrace/scene/texture.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"
#include "layertrace/util/parallel.h"
#include "test_util.h"

namespace lt {
namespace {

std::vector<uint8_t> rgbaPixels(int w, int h, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> px(size_t(w) * size_t(h) * 4);
  for (uint8_t& b : px) b = uint8_t(rng() & 0xFFu);
  return px;
}

glm::vec4 texelLinear(const uint8_t* p) {
  return {srgb8ToLinear(p[0]), srgb8ToLinear(p[1]), srgb8ToLinear(p[2]), float(p[3]) / 255.0f};
}

TEST(Texture, Srgb8RoundTripsEveryCode) {
  for (uint32_t c = 0; c < 256; ++c) EXPECT_EQ(linearToSrgb8(srgb8ToLinear(c)), c) << c;
  EXPECT_EQ(linearToSrgb8(-1.0f), 0u);
  EXPECT_EQ(linearToSrgb8(2.0f), 255u);
  EXPECT_EQ(linearToSrgb8(std::nanf("")), 0u);
  // The nearest code in sRGB space, as packAlbedoSpec's lround(encode(v) · 255).
  for (int i = 0; i <= 1000; ++i) {
    const float v = float(i) / 1000.0f;
    const float s = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
    EXPECT_NEAR(double(linearToSrgb8(v)), double(s) * 255.0, 0.5 + 1e-3) << v;
  }
}

// The bucketed walk of linearToSrgb8 is the binary search it replaces (the count of thresholds
// ≤ v), bit for bit: at every threshold and its float neighbours, and over [0, 1] in float
// steps of 257 floats.
TEST(Texture, Srgb8EncodingEqualsTheThresholdSearch) {
  std::vector<float> thresholds;
  for (uint32_t c = 0; c < 255; ++c) thresholds.push_back(srgb8Threshold(c));
  ASSERT_TRUE(std::is_sorted(thresholds.begin(), thresholds.end()));
  auto search = [&](float v) { return v > 0.0f ? uint32_t(std::upper_bound(thresholds.begin(), thresholds.end(), v) - thresholds.begin()) : 0u; };
  for (float t : thresholds)
    for (float v : {std::nextafter(t, 0.0f), t, std::nextafter(t, 2.0f)}) ASSERT_EQ(linearToSrgb8(v), search(v)) << v;
  size_t checked = 0;
  for (uint32_t bits = 0; bits <= std::bit_cast<uint32_t>(1.0f); bits += 257, ++checked) {
    const float v = std::bit_cast<float>(bits);
    ASSERT_EQ(linearToSrgb8(v), search(v)) << v;
  }
  EXPECT_GT(checked, 4'000'000u);
}

TEST(Texture, MipChainHalvesSidesAndAveragesInLinearSpace) {
  const int w = 6, h = 3;
  const std::vector<uint8_t> px = rgbaPixels(w, h, 1);
  const Texture t = makeTexture("t", w, h, px.data());
  ASSERT_EQ(t.levels.size(), 3u);  // 6×3, 3×1, 1×1
  EXPECT_EQ(t.levels[1].width, 3);
  EXPECT_EQ(t.levels[1].height, 1);
  EXPECT_EQ(t.levels[2].width, 1);
  EXPECT_EQ(t.levels[2].height, 1);
  // Level 1's texel (x, 0) is the mean of level 0's 2 × 2 block at (2x, 0).
  for (int x = 0; x < 3; ++x) {
    glm::vec4 sum(0.0f);
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) sum += texelLinear(&px[(size_t(j) * w + size_t(2 * x + i)) * 4]);
    const uint32_t texel = t.texels[t.levels[1].offset + size_t(x)];
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(srgb8ToLinear((texel >> (8 * c)) & 0xFF), sum[c] / 4.0f, 0.01f);
    EXPECT_NEAR(float(texel >> 24) / 255.0f, sum.w / 4.0f, 0.5f / 255.0f + 1e-6f);
  }
}

TEST(Texture, TrilinearSamplesTexelsAndBlendsLevels) {
  const int w = 8, h = 4;
  const std::vector<uint8_t> px = rgbaPixels(w, h, 2);
  const Texture t = makeTexture("t", w, h, px.data());
  // Level 0 at a texel's centre is that texel; row y is v = 1 - (y + 0.5) / h.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const glm::vec2 uv{(float(x) + 0.5f) / w, 1.0f - (float(y) + 0.5f) / h};
      const glm::vec4 s = sampleTrilinear(t, uv, 0.0f, TextureWrap::Repeat, TextureWrap::Repeat);
      const glm::vec4 e = texelLinear(&px[(size_t(y) * w + size_t(x)) * 4]);
      for (int c = 0; c < 4; ++c) EXPECT_NEAR(s[c], e[c], 1e-5f) << x << "," << y;
    }
  // Between two texels: their mean (bilinear); between two levels: the levels' blend.
  const glm::vec2 mid{2.0f / w, 1.0f - 0.5f / h};
  const glm::vec4 a = texelLinear(&px[1 * 4]), b = texelLinear(&px[2 * 4]);
  EXPECT_NEAR(sampleTrilinear(t, mid, 0.0f, TextureWrap::Repeat, TextureWrap::Repeat).x, 0.5f * (a.x + b.x), 1e-5f);
  const glm::vec2 uv{0.3f, 0.6f};
  const glm::vec4 l1 = sampleTrilinear(t, uv, 1.0f, TextureWrap::Repeat, TextureWrap::Repeat);
  const glm::vec4 l2 = sampleTrilinear(t, uv, 2.0f, TextureWrap::Repeat, TextureWrap::Repeat);
  const glm::vec4 l = sampleTrilinear(t, uv, 1.25f, TextureWrap::Repeat, TextureWrap::Repeat);
  for (int c = 0; c < 4; ++c) EXPECT_NEAR(l[c], 0.75f * l1[c] + 0.25f * l2[c], 1e-5f);
  // Past the chain: its last level, the mean (to the 8-bit rounding of each level on the way).
  const glm::vec4 far = sampleTrilinear(t, uv, 40.0f, TextureWrap::Repeat, TextureWrap::Repeat), mean = t.mean();
  for (int c = 0; c < 4; ++c) EXPECT_NEAR(far[c], mean[c], 0.01f);
}

TEST(Texture, WrapModesPickTheTexelsTheirRulesName) {
  const int w = 4, h = 1;
  std::vector<uint8_t> px(size_t(w) * 4, 255);
  for (int x = 0; x < w; ++x) px[size_t(x) * 4 + 3] = uint8_t(10 * (x + 1));  // alpha names the texel
  const Texture t = makeTexture("t", w, h, px.data());
  auto alpha = [&](float u, TextureWrap mode) { return int(std::lround(alphaNearest(t, {u, 0.5f}, mode, mode) * 255.0f)); };
  EXPECT_EQ(alpha(0.1f, TextureWrap::Repeat), 10);
  EXPECT_EQ(alpha(1.1f, TextureWrap::Repeat), 10);
  EXPECT_EQ(alpha(-0.1f, TextureWrap::Repeat), 40);
  EXPECT_EQ(alpha(1.1f, TextureWrap::Clamp), 40);
  EXPECT_EQ(alpha(-3.0f, TextureWrap::Clamp), 10);
  EXPECT_EQ(alpha(1.1f, TextureWrap::Mirror), 40);   // mirrored: [1, 2) runs backwards
  EXPECT_EQ(alpha(1.9f, TextureWrap::Mirror), 10);
  EXPECT_EQ(alpha(-0.1f, TextureWrap::Mirror), 10);
  EXPECT_EQ(alpha(2.1f, TextureWrap::Mirror), 10);
  // Huge and non-finite coordinates stay defined and keep their period.
  EXPECT_EQ(alpha(1.0e9f + 0.0f, TextureWrap::Repeat), alpha(0.0f, TextureWrap::Repeat));
  EXPECT_EQ(alpha(5.0e6f, TextureWrap::Clamp), 40);
  EXPECT_EQ(alpha(std::numeric_limits<float>::infinity(), TextureWrap::Repeat), 10);
  EXPECT_EQ(alpha(std::nanf(""), TextureWrap::Mirror), 10);
}

// DirectDraw Surfaces, which stb_image does not read: DXT1 (4- and 3-colour blocks), DXT5's
// interpolated alpha and uncompressed 32-bit pixels decode to the texels the format defines;
// truncated data decodes to nothing and an oversized header is refused.
std::string ddsHeader(uint32_t width, uint32_t height, uint32_t pfFlags, const char* fourcc, uint32_t bits = 0,
                      std::array<uint32_t, 4> masks = {}) {
  std::string h(128, '\0');
  auto put = [&](size_t at, uint32_t v) { for (int k = 0; k < 4; ++k) h[at + size_t(k)] = char((v >> (8 * k)) & 0xFFu); };
  std::memcpy(h.data(), "DDS ", 4);
  put(4, 124), put(12, height), put(16, width), put(76, 32), put(80, pfFlags), put(88, bits);
  if (fourcc) std::memcpy(&h[84], fourcc, 4);
  for (int c = 0; c < 4; ++c) put(92 + 4 * size_t(c), masks[size_t(c)]);
  return h;
}

std::optional<Rgba8Image> decode(const std::string& bytes) {
  return decodeRgba8(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), "test.dds");
}

TEST(Texture, DdsBlocksAndPixelsDecodeAsTheFormatDefines) {
  // DXT1, c0 = red > c1 = blue: 4 colours; texel i of each row takes index i.
  std::string dxt1 = ddsHeader(4, 4, 0x4, "DXT1") + std::string("\x00\xF8\x1F\x00\xE4\xE4\xE4\xE4", 8);
  std::optional<Rgba8Image> img = decode(dxt1);
  ASSERT_TRUE(img);
  const uint8_t want[4][4] = {{255, 0, 0, 255}, {0, 0, 255, 255}, {170, 0, 85, 255}, {85, 0, 170, 255}};
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x)
      for (int c = 0; c < 4; ++c) EXPECT_EQ(img->pixels[size_t(y * 4 + x) * 4 + size_t(c)], want[x][c]) << x << "," << y << "," << c;
  // c0 <= c1: 3 colours and transparent black at index 3.
  img = decode(ddsHeader(4, 4, 0x4, "DXT1") + std::string("\x1F\x00\x00\xF8\xFF\xFF\xFF\xFF", 8));
  ASSERT_TRUE(img);
  EXPECT_EQ(img->pixels[3], 0);
  EXPECT_EQ(img->pixels[0], 0);
  // DXT5: alphas 255 and 0 and six between; texel i takes alpha index i % 8.
  std::string block("\xFF\x00", 2);
  uint64_t indices = 0;
  for (int i = 0; i < 16; ++i) indices |= uint64_t(i % 8) << (3 * i);
  for (int k = 0; k < 6; ++k) block += char((indices >> (8 * k)) & 0xFFu);
  block += std::string("\x00\xF8\x1F\x00\x00\x00\x00\x00", 8);
  img = decode(ddsHeader(4, 4, 0x4, "DXT5") + block);
  ASSERT_TRUE(img);
  EXPECT_EQ(img->pixels[3], 255);
  EXPECT_EQ(img->pixels[4 + 3], 0);
  EXPECT_EQ(img->pixels[8 + 3], (6 * 255) / 7);
  EXPECT_EQ(img->pixels[0], 255) << "colour index 0: red";
  // Uncompressed BGRA, 2 × 1.
  img = decode(ddsHeader(2, 1, 0x41, nullptr, 32, {0x00FF0000u, 0x0000FF00u, 0x000000FFu, 0xFF000000u}) +
               std::string("\x30\x20\x10\x80\x01\x02\x03\xFF", 8));
  ASSERT_TRUE(img);
  const uint8_t rgba[8] = {0x10, 0x20, 0x30, 0x80, 0x03, 0x02, 0x01, 0xFF};
  for (int i = 0; i < 8; ++i) EXPECT_EQ(img->pixels[size_t(i)], rgba[i]) << i;
  // Truncated blocks, an unknown block format, an oversized header.
  EXPECT_FALSE(decode(dxt1.substr(0, dxt1.size() - 1)));
  EXPECT_FALSE(decode(ddsHeader(4, 4, 0x4, "ATI2") + std::string(16, '\0')));
  EXPECT_THROW(decode(ddsHeader(20000, 4, 0x4, "DXT1") + std::string(8, '\0')), InputError);
}

// --- the checkerboard grate ------------------------------------------------------------------

constexpr int kChecks = 8;  ///< texels per side of the grate's texture

/// A wall at z = -4, a floor at y = -1 and, between the camera and the wall, a grate at z = -2
/// whose 8 × 8 texture is a checkerboard of opaque coloured texels and fully transparent ones,
/// alpha-tested at 0.5 and repeated twice across the quad.
Scene grateScene() {
  Scene s;
  s.name = "grate";
  s.materials.push_back(Material{"wall"});
  s.materials[0].albedo = glm::vec3(0.2f, 0.6f, 0.3f);
  Material grate{"grate"};
  grate.albedo = glm::vec3(1.0f);
  grate.baseTexture = 0;
  grate.alphaCutoff = 0.5f;
  s.materials.push_back(grate);
  std::vector<uint8_t> px(size_t(kChecks) * kChecks * 4);
  for (int y = 0; y < kChecks; ++y)
    for (int x = 0; x < kChecks; ++x) {
      uint8_t* p = &px[(size_t(y) * kChecks + size_t(x)) * 4];
      p[0] = uint8_t(40 + 25 * x), p[1] = uint8_t(40 + 25 * y), p[2] = 200, p[3] = (x + y) % 2 ? 0 : 255;
    }
  s.textures.push_back(std::make_shared<const Texture>(makeTexture("checks", kChecks, kChecks, px.data())));
  auto quad = [&](glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, uint32_t m, float repeat) {
    const auto base = uint32_t(s.positions.size());
    for (const glm::vec3& p : {a, b, c, d}) s.positions.push_back(p);
    for (const glm::vec2& t : {glm::vec2(0, 0), glm::vec2(repeat, 0), glm::vec2(repeat, repeat), glm::vec2(0, repeat)}) s.texcoords.push_back(t);
    s.triangles.push_back({base, base + 1, base + 2});
    s.triangles.push_back({base, base + 2, base + 3});
    s.triMaterial.push_back(m);
    s.triMaterial.push_back(m);
  };
  quad({-3, -1, -4}, {3, -1, -4}, {3, 3, -4}, {-3, 3, -4}, 0, 1.0f);
  quad({-3, -1, 0}, {3, -1, 0}, {3, -1, -4}, {-3, -1, -4}, 0, 1.0f);
  quad({-1.3f, -0.9f, -2.1f}, {1.2f, -0.8f, -1.9f}, {1.25f, 1.6f, -2.0f}, {-1.2f, 1.55f, -2.05f}, 1, 2.0f);
  s.finalize("grate");
  return s;
}

CameraDesc grateView() {
  CameraDesc d;
  d.eye = {0.35f, 0.4f, 1.5f};
  d.target = {0.0f, 0.2f, -3.0f};
  d.fovY = 55.0f;
  d.near = 0.05f;
  d.far = 20.0f;
  return d;
}

TEST(CutOut, CapturesMatchEmbreeThroughTheHoles) {
  const Scene s = grateScene();
  ASSERT_TRUE(s.anyCutOut());
  const int W = 200, H = 150;
  Frame f = test::frameOf(s, grateView(), W, H, 4, 0.05f);
  const EmbreeScene embree(f.scene);
  FragmentLists lists = rasterize(f.scene, f.camera, RasterConfig{});
  const VerifyResult v = verifyLayers(lists, f.camera, embree);
  EXPECT_EQ(v.matching, v.pixels) << "fewer " << v.fewerFragments << " more " << v.moreFragments << " depth " << v.depthMismatch;
  // The grate both stops rays (its fragments) and lets them through (the wall behind a hole).
  size_t onGrate = 0, throughHoles = 0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const glm::vec3 dir = f.camera.dirToWorld(f.camera.rayThrough({float(x) + 0.5f, float(y) + 0.5f}));
      const GeoHit h = embree.intersect(f.camera.desc().eye, dir, 0.0f, 1e30f);
      if (!h.hit()) continue;
      if (s.triMaterial[h.triangle] == 1) ++onGrate;
      // Inside the grate's screen area, a first hit on the wall or the floor went through a hole.
      else if (x > W / 4 && x < 3 * W / 4 && y > H / 4 && y < 3 * H / 4) ++throughHoles;
    }
  EXPECT_GT(onGrate, size_t(W * H / 20));
  EXPECT_GT(throughHoles, size_t(W * H / 20));
  // Without the alpha test the grate is solid: the same view then has no holes.
  Scene solid = s;
  solid.materials[1].alphaCutoff = -1.0f;
  const EmbreeScene solidEmbree(solid);
  const VerifyResult mixed = verifyLayers(lists, f.camera, solidEmbree);
  EXPECT_GT(mixed.fewerFragments, uint64_t(W * H / 20)) << "the test must see the holes";
  // The tile-local capture, with and without lists, and depth peeling keep the same fragments.
  LayerConfig lc;
  lc.k = 4;
  lc.thickness = 0.05f;
  LayerCapture capture;
  LayerArrays tiles, withLists, peeled;
  std::vector<uint32_t> complexity;
  FragmentLists lists2;
  capture.capture(f.scene, f.camera, RasterConfig{}, lc, tiles, complexity);
  capture.captureWithLists(f.scene, f.camera, RasterConfig{}, lc, withLists, lists2);
  capture.capturePeeled(f.scene, f.camera, RasterConfig{}, lc, peeled, complexity);
  EXPECT_EQ(compareLayerArrays(tiles, withLists, 0.0f).sameBits, compareLayerArrays(tiles, withLists, 0.0f).filled);
  EXPECT_EQ(compareLayerArrays(tiles, peeled, 0.0f).sameBits, compareLayerArrays(tiles, peeled, 0.0f).filled);
  EXPECT_EQ(compareLayerArrays(tiles, f.layers, 0.0f).sameBits, compareLayerArrays(tiles, f.layers, 0.0f).filled);
  EXPECT_EQ(lists2.generated, lists.generated) << "both list pipelines discard the same fragments";
  const VerifyResult va = verifyLayerArrays(tiles, f.camera, embree);
  EXPECT_EQ(va.matching, va.pixels);
}

TEST(CutOut, GridAndEmbreeAnswerAlikeForEveryRayKind) {
  const Scene s = grateScene();
  const IrregularGrid grid(s);
  const EmbreeScene embree(s);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  size_t differ = 0, passed = 0;
  for (int i = 0; i < 20000; ++i) {
    // Rays from in front of the grate towards the wall, crossing it at random points.
    const glm::vec3 o{u(rng) * 2.0f, u(rng) * 1.5f + 0.5f, 1.0f};
    const glm::vec3 target{u(rng) * 1.2f, u(rng) * 1.2f + 0.35f, -2.0f};
    const glm::vec3 d = glm::normalize(target - o);
    const GeoHit e = embree.intersect(o, d, 0.0f, 1e30f), g = grid.intersect(o, d, 0.0f, 1e30f);
    differ += e.triangle != g.triangle || (e.hit() && std::abs(e.t - g.t) > 1e-5f * e.t);
    differ += embree.occluded(o, d, 0.0f, 3.5f) != grid.occluded(o, d, 0.0f, 3.5f);
    passed += e.hit() && s.triMaterial[e.triangle] == 0;
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(passed, 5000u) << "rays through the holes";
  EXPECT_LT(passed, 15000u) << "rays stopped by the bars";
}

TEST(CutOut, GeometricHitsShadeTheTexelsTheCaptureStores) {
  const Scene s = grateScene();
  const int W = 160, H = 120;
  Frame f = test::frameOf(s, grateView(), W, H, 1, 0.05f);
  const EmbreeScene embree(f.scene);
  const GeometricHits hits(f.scene, f.camera);
  size_t compared = 0, close = 0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t p = f.layers.pixelIndex(x, y);
      if (f.layers.count[p] == 0) continue;
      const glm::vec3 dirCam = f.camera.rayThrough({float(x) + 0.5f, float(y) + 0.5f});
      Ray r = test::freeRay(glm::vec3(0.0f), dirCam);
      const GeoHit g = embree.intersect(f.camera.desc().eye, f.camera.dirToWorld(r.dir), 0.0f, 1e30f);
      if (!g.hit() || g.triangle != f.layers.triangle[p * size_t(f.layers.k)]) continue;
      const uint32_t a = hits.makeHit(r, g).albedoSpec, b = f.layers.slots[p * size_t(f.layers.k)].albedoSpec;
      ++compared;
      bool near = true;
      for (int c = 0; c < 4; ++c) near = near && std::abs(int((a >> (8 * c)) & 0xFF) - int((b >> (8 * c)) & 0xFF)) <= 1;
      close += near;
    }
  ASSERT_GT(compared, size_t(W * H / 2));
  // The same texels at the same level: equal to a unit of the last bit, except where a pixel
  // centre falls within rounding of a texel edge (bilinear weights of 0 and 1 then swap).
  EXPECT_GE(double(close), 0.995 * double(compared));
  // And the texture shows: the grate's fragments are not all one colour.
  std::vector<uint32_t> colours;
  for (size_t p = 0; p < f.layers.count.size(); ++p)
    if (f.layers.count[p] && s.triMaterial[f.layers.triangle[p * size_t(f.layers.k)]] == 1) colours.push_back(f.layers.slots[p].albedoSpec);
  std::sort(colours.begin(), colours.end());
  EXPECT_GT(std::unique(colours.begin(), colours.end()) - colours.begin(), 16);
}

TEST(CutOut, FlattenedTexturesMakeTheGrateSolidAndItsMeanColour) {
  Scene s = grateScene();
  const glm::vec4 mean = s.textures[0]->mean();
  flattenTextures(s);
  EXPECT_FALSE(s.anyCutOut());
  EXPECT_TRUE(s.textures.empty() && s.texcoords.empty());
  EXPECT_NEAR(s.materials[1].albedo.x, mean.x, 1e-6f);
  EXPECT_NEAR(s.materials[1].albedo.z, mean.z, 1e-6f);
}

}  // namespace
}  // namespace lt
