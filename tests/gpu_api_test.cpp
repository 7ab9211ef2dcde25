// The public GPU API (api/gpu.h) driven as a renderer drives it: from a context the test makes
// itself with EGL, with the test's own GL objects and state around the calls. Its picture must
// be the CLI's (`render --device gpu`) byte for byte, its tracer's answers the CPU tracer's, and
// the caller's state as it was, also after an error.
#if LAYERTRACE_HAS_GPU

#include <array>
#include <cstddef>
#include <cstring>
#include <limits>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>
#include <stb_image.h>

#include "layertrace/api/gpu.h"
#include "layertrace/api/layertrace.h"
#include "layertrace/pipeline/frame.h"
#include "test_util.h"

namespace lt {
namespace {

/// A headless OpenGL 4.5 core context made here, not by layertrace (Mesa's surfaceless EGL, as
/// on the test machines), current on the test's thread while a test runs.
class GpuApi : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // The GPU driver is not instrumented, and the sanitized builds make no CLI to compare with.
    if (test::sanitized()) return;
    if (!epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_MESA_platform_surfaceless")) return;
    display_ = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    EGLint major = 0, minor = 0;
    if (display_ == EGL_NO_DISPLAY || !eglInitialize(display_, &major, &minor) || !eglBindAPI(EGL_OPENGL_API)) return;
    const EGLint attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5, EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                 EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    context_ = eglCreateContext(display_, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attributes);
  }
  static void TearDownTestSuite() {
    if (context_ != EGL_NO_CONTEXT) {
      eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      eglDestroyContext(display_, context_);
    }
  }
  void SetUp() override {
    if (context_ == EGL_NO_CONTEXT || !eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_))
      GTEST_SKIP() << (test::sanitized() ? "sanitized build: the GPU driver is not instrumented"
                                         : "no surfaceless EGL context here");
  }
  void TearDown() override { eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT); }

  static GLuint texture(GLenum format, int width, int height) {
    GLuint t = 0;
    glCreateTextures(GL_TEXTURE_2D, 1, &t);
    glTextureStorage2D(t, 1, format, width, height);
    return t;
  }

  static inline EGLDisplay display_ = EGL_NO_DISPLAY;
  static inline EGLContext context_ = EGL_NO_CONTEXT;
};

/// The state a renderer might have set, read back whole.
struct CallerState {
  GLint program = 0, vertexArray = 0, framebuffer = 0, viewport[4] = {}, storage3 = 0, storage = 0, unpackAlignment = 0, unpackBuffer = 0;
  GLboolean scissor = GL_FALSE, depth = GL_FALSE;
  static CallerState read() {
    CallerState s;
    glGetIntegerv(GL_CURRENT_PROGRAM, &s.program);
    glGetIntegerv(GL_VERTEX_ARRAY_BINDING, &s.vertexArray);
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &s.framebuffer);
    glGetIntegerv(GL_VIEWPORT, s.viewport);
    glGetIntegeri_v(GL_SHADER_STORAGE_BUFFER_BINDING, 3, &s.storage3);
    glGetIntegerv(GL_SHADER_STORAGE_BUFFER_BINDING, &s.storage);
    glGetIntegerv(GL_UNPACK_ALIGNMENT, &s.unpackAlignment);
    glGetIntegerv(GL_PIXEL_UNPACK_BUFFER_BINDING, &s.unpackBuffer);
    s.scissor = glIsEnabled(GL_SCISSOR_TEST);
    s.depth = glIsEnabled(GL_DEPTH_TEST);
    return s;
  }
  bool operator==(const CallerState& o) const {
    return program == o.program && vertexArray == o.vertexArray && framebuffer == o.framebuffer &&
           std::memcmp(viewport, o.viewport, sizeof viewport) == 0 && storage3 == o.storage3 && storage == o.storage &&
           unpackAlignment == o.unpackAlignment && unpackBuffer == o.unpackBuffer && scissor == o.scissor && depth == o.depth;
  }
};

/// Sets a renderer's state: its own vertex array, a buffer on storage binding 3, a scissored
/// viewport, depth test, 1-byte unpack alignment and an unpack buffer.
CallerState setCallerState(GLuint& vao, GLuint& buffer) {
  glCreateVertexArrays(1, &vao);
  glBindVertexArray(vao);
  glCreateBuffers(1, &buffer);
  glNamedBufferStorage(buffer, 256, nullptr, GL_DYNAMIC_STORAGE_BIT);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, buffer);
  glBindBuffer(GL_PIXEL_UNPACK_BUFFER, buffer);
  glViewport(1, 2, 30, 40);
  glEnable(GL_SCISSOR_TEST);
  glEnable(GL_DEPTH_TEST);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  return CallerState::read();
}

/// Expects the top-left W × H texels of the RGBA8 `target` (`rowTexels` a row) to be the CLI's
/// PNG of `render SCENE --device gpu --tracer TRACER --effect reflection --bounces 2` at W × H,
/// byte for byte, and lit.
void expectCliPicture(const std::string& scenePath, GLuint target, int W, int H, int rowTexels, const std::string& tracer = "hssr") {
  GLint height = 0;
  glGetTextureLevelParameteriv(target, 0, GL_TEXTURE_HEIGHT, &height);
  std::vector<uint8_t> texels(size_t(rowTexels) * size_t(height) * 4);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glGetTextureImage(target, 0, GL_RGBA, GL_UNSIGNED_BYTE, GLsizei(texels.size()), texels.data());
  test::TempDir dir;
  ASSERT_EQ(test::runCli("render " + scenePath + " --device gpu --tracer " + tracer + " --effect reflection --bounces 2 --quiet --width " +
                         std::to_string(W) + " --height " + std::to_string(H) + " -o " + (dir / "cli.png")),
            0);
  int w = 0, h = 0, n = 0;
  unsigned char* cli = stbi_load((dir / "cli.png").c_str(), &w, &h, &n, 3);
  ASSERT_NE(cli, nullptr);
  ASSERT_EQ(w, W);
  ASSERT_EQ(h, H);
  size_t differ = 0, lit = 0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < 3; ++c) {
        const uint8_t mine = texels[(size_t(y) * size_t(rowTexels) + size_t(x)) * 4 + size_t(c)];
        const uint8_t theirs = cli[(size_t(y) * W + size_t(x)) * 3 + size_t(c)];
        differ += mine != theirs;
        lit += theirs > 8;
      }
  stbi_image_free(cli);
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(lit, size_t(W * H));
}

/// Rays from points in front of the default view in random directions (camera space), as the
/// CPU's Rays and as the GPU API's records.
void randomRays(uint32_t seed, std::vector<Ray>& cpuRays, std::vector<GpuRayRecord>& records) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < 3000; ++i) {
    glm::vec3 d(u(rng), u(rng), u(rng));
    if (glm::length(d) < 0.1f) continue;
    d = glm::normalize(d);
    const glm::vec3 origin = glm::vec3(u(rng) * 0.3f, u(rng) * 0.3f, -1.5f - u(rng));
    Ray r;
    r.origin = origin, r.dir = d, r.maxDistance = 20.0f, r.startsOnSurface = false;
    cpuRays.push_back(r);
    records.push_back({{origin.x, origin.y, origin.z}, r.maxDistance, {d.x, d.y, d.z}, 0.0f});
  }
}

/// `renderer`'s answers to `records`, through buffers of the test's own.
std::vector<GpuHitRecord> traceRecords(const GpuRenderer& renderer, const std::vector<GpuRayRecord>& records) {
  GLuint buffers[2] = {};
  glCreateBuffers(2, buffers);
  glNamedBufferStorage(buffers[0], GLsizeiptr(records.size() * sizeof(GpuRayRecord)), records.data(), 0);
  glNamedBufferStorage(buffers[1], GLsizeiptr(records.size() * sizeof(GpuHitRecord)), nullptr, 0);
  renderer.trace(buffers[0], buffers[1], records.size());
  std::vector<GpuHitRecord> hits(records.size());
  glGetNamedBufferSubData(buffers[1], 0, GLsizeiptr(hits.size() * sizeof(GpuHitRecord)), hits.data());
  glDeleteBuffers(2, buffers);
  return hits;
}

/// How the GPU's answers `got` agree with the CPU tracer's `want` to the same rays.
struct Agreement {
  size_t differ = 0;  ///< rays answered differently: hit or miss, the pixel, and with `layers` the layer
  size_t hits = 0;    ///< rays the CPU tracer hit
};
Agreement agreement(const std::vector<GpuHitRecord>& got, const std::vector<TraceHit>& want, bool layers = true) {
  Agreement a;
  for (size_t i = 0; i < want.size(); ++i) {
    const bool gpuHit = got[i].layer >= 0;
    a.hits += want[i].hit;
    a.differ += gpuHit != want[i].hit ||
                (gpuHit && (got[i].x != want[i].x || got[i].y != want[i].y || (layers && got[i].layer != want[i].layer)));
  }
  return a;
}

TEST_F(GpuApi, RendersIntoTheCallersTextureTheCliPictureAndLeavesItsState) {
  const int W = 120, H = 72;
  const std::string scenePath = test::sourceDir() + "/scenes/default.json";
  const TriangleScene scene = TriangleScene::load(scenePath);
  const View view = scene.view("", W, H);
  GpuDevice device;
  EXPECT_FALSE(device.renderer().empty());
  GpuRenderer renderer(device, scene);
  const GLuint target = texture(GL_RGBA8, W + 8, H + 4);  // larger than the view: the top-left W × H is written
  GLuint vao = 0, buffer = 0;
  const CallerState before = setCallerState(vao, buffer);
  GpuEffectRequest effect;
  effect.bounces = 2;
  const GpuFrameInfo info = renderer.render(view, effect, target);
  EXPECT_TRUE(CallerState::read() == before);
  EXPECT_GT(info.rays, uint64_t(W * H / 4));
  EXPECT_GT(info.fragments, uint64_t(W * H));

  // The picture, row 0 the top row, against the CLI's PNG of the same view.
  expectCliPicture(scenePath, target, W, H, W + 8);

  // An error leaves the state too: a texture smaller than the view, named with its size.
  const GLuint small = texture(GL_RGBA8, W / 2, H);
  try {
    renderer.render(view, effect, small);
    ADD_FAILURE() << "a small texture was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(std::to_string(W / 2) + "x" + std::to_string(H)), std::string::npos) << e.what();
  }
  const GLuint r8 = texture(GL_R8, W, H);
  EXPECT_THROW(renderer.render(view, effect, r8), std::invalid_argument);
  EXPECT_TRUE(CallerState::read() == before);
  const GLuint textures[] = {target, small, r8};
  glDeleteTextures(3, textures);
  glDeleteBuffers(1, &buffer);
  glDeleteVertexArrays(1, &vao);
}

// A renderer's own geometry pass: its vertex buffers (the scene's triangles, three vertices
// each), its vertex array, its vertex shader with a uniform of its own, two draw calls. The
// capture, the effect and the picture are then the CLI's, byte for byte; a capacity smaller than
// the scene grows, and the frame runs again.
TEST_F(GpuApi, YourDrawCallsGiveTheCliPicture) {
  const int W = 120, H = 72;
  const std::string scenePath = test::sourceDir() + "/scenes/default.json";
  const TriangleScene scene = TriangleScene::load(scenePath);
  const View view = scene.view("", W, H);
  struct Vertex {
    glm::vec3 position, normal;
    uint32_t material;
  };
  std::vector<Vertex> vertices;
  for (size_t t = 0; t < scene.triangleCount(); ++t)
    for (int i = 0; i < 3; ++i) {
      const uint32_t v = scene.triangles()[t][i];
      vertices.push_back({scene.positions()[v], scene.normals()[v], scene.materialOfTriangle()[t]});
    }
  GLuint buffer = 0, vao = 0;
  glCreateBuffers(1, &buffer);
  glNamedBufferStorage(buffer, GLsizeiptr(vertices.size() * sizeof(Vertex)), vertices.data(), 0);
  glCreateVertexArrays(1, &vao);
  glVertexArrayVertexBuffer(vao, 0, buffer, 0, sizeof(Vertex));
  glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, offsetof(Vertex, position));
  glVertexArrayAttribFormat(vao, 1, 3, GL_FLOAT, GL_FALSE, offsetof(Vertex, normal));
  glVertexArrayAttribIFormat(vao, 2, 1, GL_UNSIGNED_INT, offsetof(Vertex, material));
  for (GLuint a = 0; a < 3; ++a) glEnableVertexArrayAttrib(vao, a), glVertexArrayAttribBinding(vao, a, 0);

  GpuDevice device;
  GpuGeometry geometry;
  geometry.vertexShader = R"(#version 450
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in uint material;
uniform float uScale;
out vec3 ltPosition;
out vec3 ltNormal;
flat out uint ltMaterial;
void main() {
  ltPosition = position * uScale;
  ltNormal = normal;
  ltMaterial = material;
  gl_Position = vec4(position, 1.0);
})";
  geometry.maxTriangles = scene.triangleCount() / 3;
  GpuRenderer renderer(device, scene, geometry);
  const GLuint target = texture(GL_RGBA8, W, H);
  GLuint callerVao = 0, callerBuffer = 0;
  const CallerState before = setCallerState(callerVao, callerBuffer);
  GpuEffectRequest effect;
  effect.bounces = 2;
  int calls = 0;
  const GpuDrawCalls draw = [&](uint32_t program) {
    ++calls;
    glProgramUniform1f(program, glGetUniformLocation(program, "uScale"), 1.0f);
    glBindVertexArray(vao);
    const GLsizei half = GLsizei(scene.triangleCount() / 2);
    glDrawArrays(GL_TRIANGLES, 0, 3 * half);
    glDrawArrays(GL_TRIANGLES, 3 * half, GLsizei(3 * scene.triangleCount()) - 3 * half);
  };
  const GpuFrameInfo grown = renderer.render(view, effect, target, draw);
  EXPECT_TRUE(CallerState::read() == before);
  EXPECT_EQ(grown.triangles, scene.triangleCount());
  EXPECT_GE(grown.attempts, 2);
  EXPECT_GE(calls, 2);
  expectCliPicture(scenePath, target, W, H, W);

  // The next frame fits: one attempt, the same counts.
  calls = 0;
  const GpuFrameInfo steady = renderer.render(view, effect, target, draw);
  EXPECT_EQ(steady.attempts, 1);
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(steady.fragments, grown.fragments);
  EXPECT_EQ(steady.hits, grown.hits);
  EXPECT_TRUE(CallerState::read() == before);

  // Errors, in one line, with the state as it was: a renderer of geometry without draw calls, a
  // vertex shader without the outputs, one that does not compile.
  EXPECT_THROW(renderer.render(view, effect, target), std::invalid_argument);
  GpuGeometry bad = geometry;
  bad.vertexShader = "#version 450\nout vec3 ltPosition;\nvoid main() { ltPosition = vec3(0.0); }\n";
  EXPECT_THROW(GpuRenderer(device, scene, bad), std::invalid_argument);
  bad.vertexShader = "#version 450\nvoid main() { gl_Position = undeclared; }\n";
  try {
    GpuRenderer failing(device, scene, bad);
    ADD_FAILURE() << "a vertex shader that does not compile was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("does not compile"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(CallerState::read() == before);
  glDeleteTextures(1, &target);
  const GLuint buffers[] = {buffer, callerBuffer}, arrays[] = {vao, callerVao};
  glDeleteBuffers(2, buffers);
  glDeleteVertexArrays(2, arrays);
}

// Rays from the caller's buffer, answered into the caller's buffer on the device: the CPU
// tracer's answers over the same view's layers, ray for ray (llvmpipe captures the CPU's layers
// to the bit).
TEST_F(GpuApi, TracesTheCallersRaysAsTheCpuTracer) {
  const int W = 96, H = 64;
  const TriangleScene scene = TriangleScene::load(test::sourceDir() + "/scenes/default.json");
  const View view = scene.view("", W, H);
  GpuDevice device;
  GpuRenderer renderer(device, scene, "hssr");
  GLuint rays = 0, hits = 0;
  glCreateBuffers(1, &rays);
  glCreateBuffers(1, &hits);
  EXPECT_THROW(renderer.trace(rays, hits, 1), std::invalid_argument);  // no frame rendered yet
  const GLuint target = texture(GL_RGBA32F, W, H);
  renderer.render(view, GpuEffectRequest{"shade"}, target);

  // Rays from points in front of the view's surfaces in random directions (camera space).
  const ScreenLayers layers = captureLayers(scene, view, 4, 6.0f);
  const ScreenTracer cpu(layers, "hssr");
  std::vector<Ray> cpuRays;
  std::vector<GpuRayRecord> records;
  randomRays(uint32_t(test::testSeed() + 71), cpuRays, records);
  glNamedBufferStorage(rays, GLsizeiptr(records.size() * sizeof(GpuRayRecord)), records.data(), 0);
  glNamedBufferStorage(hits, GLsizeiptr(records.size() * sizeof(GpuHitRecord)), nullptr, GL_DYNAMIC_STORAGE_BIT);
  try {
    renderer.trace(rays, hits, records.size() + 1);
    ADD_FAILURE() << "more rays than the buffer holds were accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(std::to_string(records.size()) + " rays, fewer than " + std::to_string(records.size() + 1)),
              std::string::npos)
        << e.what();
  }
  renderer.trace(rays, hits, records.size());
  std::vector<GpuHitRecord> got(records.size());
  glGetNamedBufferSubData(hits, 0, GLsizeiptr(got.size() * sizeof(GpuHitRecord)), got.data());
  std::vector<TraceHit> want(cpuRays.size());
  cpu.trace(cpuRays, want);
  const Agreement a = agreement(got, want);
  EXPECT_EQ(a.differ, 0u);
  EXPECT_GT(a.hits, want.size() / 4);
  glDeleteBuffers(1, &rays);
  glDeleteBuffers(1, &hits);
  glDeleteTextures(1, &target);
}

// A renderer's own k-layer arrays (here the CPU capture's of the same view, in the documented
// slot layout, each slot's material from its triangle): the march answers as over the layers
// layertrace captures, ray for ray, and the picture is the captured frame's but where the
// effects use a triangle's geometric normal, which a caller's layers do not carry.
TEST_F(GpuApi, YourLayersAreTracedAsTheCapturedOnes) {
  const int W = 120, H = 72, k = 4;
  const TriangleScene scene = TriangleScene::load(test::sourceDir() + "/scenes/default.json");
  const View view = scene.view("", W, H);
  const Frame frame = buildFrame(test::defaultSceneOptions(W, H));
  ASSERT_EQ(frame.layers.k, k);
  const size_t pixels = size_t(W) * H, slots = pixels * k;
  std::vector<uint32_t> counts(frame.layers.count.begin(), frame.layers.count.end()), materials(slots, 0);
  for (size_t s = 0; s < slots; ++s)
    if (s % k < frame.layers.count[s / k]) materials[s] = scene.materialOfTriangle()[frame.layers.triangle[s]];
  GLuint buffers[3] = {};
  glCreateBuffers(3, buffers);
  glNamedBufferStorage(buffers[0], GLsizeiptr(slots * sizeof(GpuLayerSlot)), frame.layers.slots.data(), 0);
  glNamedBufferStorage(buffers[1], GLsizeiptr(pixels * 4), counts.data(), 0);
  glNamedBufferStorage(buffers[2], GLsizeiptr(slots * 4), materials.data(), 0);
  const GpuLayers layers{buffers[0], buffers[1], buffers[2]};

  GpuDevice device;
  GpuRenderer captured(device, scene), given(device, scene, GpuLayerFormat{k});
  const GLuint pictures[2] = {texture(GL_RGBA8, W, H), texture(GL_RGBA8, W, H)};
  GLuint callerVao = 0, callerBuffer = 0;
  const CallerState before = setCallerState(callerVao, callerBuffer);
  const GpuFrameInfo a = captured.render(view, GpuEffectRequest{}, pictures[0]);
  const GpuFrameInfo b = given.render(view, GpuEffectRequest{}, pictures[1], layers);
  EXPECT_TRUE(CallerState::read() == before);
  EXPECT_EQ(b.rays, a.rays);
  EXPECT_GT(b.hits, b.rays / 4);

  std::vector<Ray> cpuRays;
  std::vector<GpuRayRecord> records;
  randomRays(uint32_t(test::testSeed() + 72), cpuRays, records);
  const std::vector<GpuHitRecord> want = traceRecords(captured, records), got = traceRecords(given, records);
  size_t differ = 0, hits = 0;
  for (size_t i = 0; i < want.size(); ++i) {
    hits += want[i].layer >= 0;
    differ += std::memcmp(&want[i], &got[i], sizeof(GpuHitRecord)) != 0;
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(hits, want.size() / 4);

  std::vector<uint8_t> texels[2];
  for (int i = 0; i < 2; ++i) {
    texels[i].resize(pixels * 4);
    glGetTextureImage(pictures[i], 0, GL_RGBA, GL_UNSIGNED_BYTE, GLsizei(texels[i].size()), texels[i].data());
  }
  size_t far = 0;
  for (size_t i = 0; i < texels[0].size(); ++i) far += std::abs(int(texels[0][i]) - int(texels[1][i])) > 2;
  EXPECT_LT(far, texels[0].size() / 100) << far << " of " << texels[0].size() << " values differ by more than 2";

  // A buffer too small is named with its size.
  try {
    given.render(scene.view("", W + 1, H), GpuEffectRequest{}, pictures[1], layers);
    ADD_FAILURE() << "layers smaller than the view were accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("layers.slots"), std::string::npos) << e.what();
  }
  EXPECT_THROW(given.render(view, GpuEffectRequest{}, pictures[1]), std::invalid_argument);  // layers, not a scene
  EXPECT_TRUE(CallerState::read() == before);
  glDeleteBuffers(3, buffers);
  glDeleteTextures(2, pictures);
  glDeleteBuffers(1, &callerBuffer);
  glDeleteVertexArrays(1, &callerVao);
}

// A renderer's G-buffer: the test draws the scene with its own program into a depth texture and
// a normal texture, with glm's perspective of the view. Rays traced through that one layer
// answer as the CPU tracer over the same depths (fromDepthBuffer), apart from the rare ray
// whose depth the two conversions of window depth round differently.
TEST_F(GpuApi, YourGBufferIsOneLayer) {
  const int W = 120, H = 72;
  const TriangleScene scene = TriangleScene::load(test::sourceDir() + "/scenes/default.json");
  const View view = scene.view("", W, H);
  const glm::mat4 viewMatrix = glm::lookAt(view.eye, view.target, view.up);
  const glm::mat4 clip = glm::perspective(glm::radians(view.fovY), float(W) / float(H), view.near, view.far) * viewMatrix;
  std::vector<glm::vec3> vertices;
  for (size_t t = 0; t < scene.triangleCount(); ++t)
    for (int i = 0; i < 3; ++i) {
      const uint32_t v = scene.triangles()[t][i];
      vertices.push_back(scene.positions()[v]);
      vertices.push_back(glm::mat3(viewMatrix) * scene.normals()[v]);
    }
  GLuint buffer = 0, vao = 0, fbo = 0, depth = texture(GL_DEPTH_COMPONENT32F, W, H), normals = texture(GL_RGBA16F, W, H);
  glCreateBuffers(1, &buffer);
  glNamedBufferStorage(buffer, GLsizeiptr(vertices.size() * sizeof(glm::vec3)), vertices.data(), 0);
  glCreateVertexArrays(1, &vao);
  glVertexArrayVertexBuffer(vao, 0, buffer, 0, 2 * sizeof(glm::vec3));
  glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribFormat(vao, 1, 3, GL_FLOAT, GL_FALSE, sizeof(glm::vec3));
  for (GLuint a = 0; a < 2; ++a) glEnableVertexArrayAttrib(vao, a), glVertexArrayAttribBinding(vao, a, 0);
  glCreateFramebuffers(1, &fbo);
  glNamedFramebufferTexture(fbo, GL_DEPTH_ATTACHMENT, depth, 0);
  glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, normals, 0);
  const char* vs = "#version 450\nlayout(location = 0) in vec3 p;\nlayout(location = 1) in vec3 n;\nuniform mat4 uClip;\nout vec3 vn;\n"
                   "void main() { vn = n; gl_Position = uClip * vec4(p, 1.0); }\n";
  const char* fs = "#version 450\nin vec3 vn;\nout vec4 colour;\nvoid main() { colour = vec4(normalize(vn), 1.0); }\n";
  const GLuint program = glCreateProgram();
  for (const auto& [stage, source] : {std::pair{GL_VERTEX_SHADER, vs}, std::pair{GL_FRAGMENT_SHADER, fs}}) {
    const GLuint shader = glCreateShader(stage);
    glShaderSource(shader, 1, &source, nullptr);
    glCompileShader(shader);
    glAttachShader(program, shader);
    glDeleteShader(shader);
  }
  glLinkProgram(program);
  GLint linked = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &linked);
  ASSERT_TRUE(linked);
  glProgramUniformMatrix4fv(program, glGetUniformLocation(program, "uClip"), 1, GL_FALSE, &clip[0][0]);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glViewport(0, 0, W, H);
  glDisable(GL_SCISSOR_TEST);  // (an earlier test's caller state may have left it on)
  const float one = 1.0f, zero[4] = {};
  glClearNamedFramebufferfv(fbo, GL_DEPTH, 0, &one);
  glClearNamedFramebufferfv(fbo, GL_COLOR, 0, zero);
  glEnable(GL_DEPTH_TEST);
  glUseProgram(program);
  glBindVertexArray(vao);
  glDrawArrays(GL_TRIANGLES, 0, GLsizei(vertices.size() / 2));
  glUseProgram(0);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glDisable(GL_DEPTH_TEST);

  GpuDevice device;
  GpuRenderer renderer(device, scene, GpuLayerFormat{1, 6.0f});
  const GLuint picture = texture(GL_RGBA8, W, H);
  const GpuFrameInfo info = renderer.render(view, GpuEffectRequest{"ao"}, picture, GpuGBuffer{depth, normals, 0});
  EXPECT_GT(info.rays, uint64_t(W * H / 2));
  EXPECT_GT(info.hits, info.rays / 20);

  // The same depths on the CPU: window depth back to camera depth, rows flipped.
  std::vector<float> window(size_t(W) * H), cameraDepth(size_t(W) * H);
  glGetTextureImage(depth, 0, GL_DEPTH_COMPONENT, GL_FLOAT, GLsizei(window.size() * 4), window.data());
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float d = window[size_t(H - 1 - y) * W + size_t(x)], ndc = 2.0f * d - 1.0f;
      cameraDepth[size_t(y) * W + size_t(x)] = d < 1.0f ? 2.0f * view.near * view.far / ((view.far + view.near) - ndc * (view.far - view.near))
                                                       : std::numeric_limits<float>::infinity();
    }
  const ScreenLayers layers = ScreenLayers::fromDepthBuffer(view, cameraDepth);
  const ScreenTracer cpu(layers, "hssr");
  std::vector<Ray> cpuRays;
  std::vector<GpuRayRecord> records;
  randomRays(uint32_t(test::testSeed() + 73), cpuRays, records);
  const std::vector<GpuHitRecord> got = traceRecords(renderer, records);
  std::vector<TraceHit> want(cpuRays.size());
  cpu.trace(cpuRays, want);
  const Agreement a = agreement(got, want, false);  // (one layer: the pixel says it all)
  EXPECT_GT(a.hits, want.size() / 4);
  EXPECT_LE(a.differ, want.size() / 200) << a.differ << " of " << want.size() << " rays answered differently";

  // A texture of another size is named.
  const GLuint small = texture(GL_RGBA16F, W / 2, H);
  try {
    renderer.render(view, GpuEffectRequest{"ao"}, picture, GpuGBuffer{depth, small, 0});
    ADD_FAILURE() << "normals of another size were accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gbuffer.normals"), std::string::npos) << e.what();
  }
  const GLuint textures[] = {depth, normals, picture, small};
  glDeleteTextures(4, textures);
  glDeleteProgram(program);
  glDeleteFramebuffers(1, &fbo);
  glDeleteBuffers(1, &buffer);
  glDeleteVertexArrays(1, &vao);
}

// SSR over the frame's layers (McGuire and Mara 2014; the front layer, or all k): the picture is
// `render --device gpu`'s (whose SSR marches layers it downloaded), and rays from the caller's
// buffer get the CPU SSR's answers over the same capture, ray for ray.
TEST_F(GpuApi, SsrMarchesTheFramesLayersAsTheCpu) {
  const int W = 120, H = 72;
  const std::string scenePath = test::sourceDir() + "/scenes/default.json";
  const TriangleScene scene = TriangleScene::load(scenePath);
  const View view = scene.view("", W, H);
  const ScreenLayers layers = captureLayers(scene, view, 4, 6.0f);
  GpuDevice device;
  for (const char* name : {"ssr", "ssr-layers"}) {
    SCOPED_TRACE(name);
    GpuRenderer renderer(device, scene, name);
    const GLuint target = texture(GL_RGBA8, W, H);
    GpuEffectRequest effect;
    effect.bounces = 2;
    const GpuFrameInfo info = renderer.render(view, effect, target);
    EXPECT_GT(info.hits, info.rays / 4);
    expectCliPicture(scenePath, target, W, H, W, name);
    glDeleteTextures(1, &target);

    const ScreenTracer cpu(layers, name);
    std::vector<Ray> cpuRays;
    std::vector<GpuRayRecord> records;
    randomRays(uint32_t(test::testSeed() + 74), cpuRays, records);
    const std::vector<GpuHitRecord> got = traceRecords(renderer, records);
    std::vector<TraceHit> want(cpuRays.size());
    cpu.trace(cpuRays, want);
    const Agreement a = agreement(got, want);
    EXPECT_EQ(a.differ, 0u);
    EXPECT_GT(a.hits, want.size() / 5);
  }
}

TEST_F(GpuApi, RefusesUnknownTracersAndParametersWithTheCliMessages) {
  const TriangleScene scene = TriangleScene::load(test::sourceDir() + "/scenes/default.json");
  GpuDevice device;
  EXPECT_THROW(GpuRenderer(device, scene, "quadtree"), std::invalid_argument);
  EXPECT_THROW(GpuRenderer(device, scene, "hssr", TracerParams().set("hssr-tau", "-1")), std::invalid_argument);
  GpuRenderer paper(device, scene, "hssr", TracerParams("paper"));  // a preset by name
  const GLuint target = texture(GL_RGBA8, 32, 24);
  EXPECT_GT(paper.render(scene.view("", 32, 24), GpuEffectRequest{}, target).rays, 0u);
  glDeleteTextures(1, &target);
}

}  // namespace
}  // namespace lt

#endif
