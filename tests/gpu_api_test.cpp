// The public GPU API (api/gpu.h) driven as a renderer drives it: from a context the test makes
// itself with EGL, with the test's own GL objects and state around the calls. Its picture must
// be the CLI's (`render --device gpu`) byte for byte, its tracer's answers the CPU tracer's, and
// the caller's state as it was, also after an error.
#if LAYERTRACE_HAS_GPU

#include <array>
#include <cstddef>
#include <cstring>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <gtest/gtest.h>
#include <stb_image.h>

#include "layertrace/api/gpu.h"
#include "layertrace/api/layertrace.h"
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
/// PNG of `render SCENE --device gpu --tracer hssr --effect reflection --bounces 2` at W × H, byte
/// for byte, and lit.
void expectCliPicture(const std::string& scenePath, GLuint target, int W, int H, int rowTexels) {
  GLint height = 0;
  glGetTextureLevelParameteriv(target, 0, GL_TEXTURE_HEIGHT, &height);
  std::vector<uint8_t> texels(size_t(rowTexels) * size_t(height) * 4);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glGetTextureImage(target, 0, GL_RGBA, GL_UNSIGNED_BYTE, GLsizei(texels.size()), texels.data());
  test::TempDir dir;
  ASSERT_EQ(test::runCli("render " + scenePath + " --device gpu --tracer hssr --effect reflection --bounces 2 --quiet --width " +
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

  // Rays from points on the view's surfaces in random directions (camera space).
  const ScreenLayers layers = captureLayers(scene, view, 4, 6.0f);
  const ScreenTracer cpu(layers, "hssr");
  std::mt19937 rng(uint32_t(test::testSeed() + 71));
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Ray> cpuRays;
  std::vector<GpuRayRecord> records;
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
  size_t differ = 0, hitCount = 0;
  for (size_t i = 0; i < want.size(); ++i) {
    const bool gpuHit = got[i].layer >= 0;
    hitCount += want[i].hit;
    differ += gpuHit != want[i].hit || (gpuHit && (got[i].x != want[i].x || got[i].y != want[i].y || got[i].layer != want[i].layer));
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(hitCount, want.size() / 4);
  glDeleteBuffers(1, &rays);
  glDeleteBuffers(1, &hits);
  glDeleteTextures(1, &target);
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
