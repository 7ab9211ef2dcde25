// HSSR reflections in an OpenGL program, through layertrace/gpu.h. The program loads a scene
// (any model assimp reads, a .pk3 or a JSON scene), keeps its triangles in a vertex buffer of its
// own, and draws them with its own shaders. For the reflections it hands layertrace its draw
// call: layertrace captures every fragment into k layers, builds the interval pyramid and traces
// the reflection bounces on the GPU (Hofmann et al. 2017), all in this program's context, and
// writes the picture into this program's texture.
//
//   gpu_reflections SCENE                   a window (GLFW): drag to orbit, scroll to move in and
//                                           out, space to switch between the program's own
//                                           shading and the reflections, escape to quit
//   gpu_reflections SCENE OUT.png [W H]     one frame without a window (EGL, no display needed),
//                                           seen from the camera of `layertrace render SCENE`
//                                           (default 640 × 360)
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <layertrace/gpu.h>
#include <layertrace/layertrace.h>
#ifndef GPU_REFLECTIONS_WINDOW  // (the build defines it 1 where GLFW is found)
#define GPU_REFLECTIONS_WINDOW 0
#endif
#if GPU_REFLECTIONS_WINDOW
#include <GLFW/glfw3.h>
#endif

namespace {

// The scene as this program draws it: three vertices a triangle, in the scene's order (so that
// layertrace sees the triangles in the order `layertrace render` does), each with its position,
// normal and material index.
struct Vertex {
  glm::vec3 position, normal;
  uint32_t material;
};

struct Mesh {
  GLuint buffer = 0, vertexArray = 0;
  GLsizei vertices = 0;
};

Mesh upload(const lt::TriangleScene& scene) {
  std::vector<Vertex> vertices;
  vertices.reserve(3 * scene.triangleCount());
  for (size_t t = 0; t < scene.triangleCount(); ++t)
    for (int corner = 0; corner < 3; ++corner) {
      const uint32_t v = scene.triangles()[t][corner];
      vertices.push_back({scene.positions()[v], scene.normals()[v], scene.materialOfTriangle()[t]});
    }
  Mesh mesh;
  mesh.vertices = GLsizei(vertices.size());
  glCreateBuffers(1, &mesh.buffer);
  glNamedBufferStorage(mesh.buffer, GLsizeiptr(vertices.size() * sizeof(Vertex)), vertices.data(), 0);
  glCreateVertexArrays(1, &mesh.vertexArray);
  glVertexArrayVertexBuffer(mesh.vertexArray, 0, mesh.buffer, 0, sizeof(Vertex));
  glVertexArrayAttribFormat(mesh.vertexArray, 0, 3, GL_FLOAT, GL_FALSE, offsetof(Vertex, position));
  glVertexArrayAttribFormat(mesh.vertexArray, 1, 3, GL_FLOAT, GL_FALSE, offsetof(Vertex, normal));
  glVertexArrayAttribIFormat(mesh.vertexArray, 2, 1, GL_UNSIGNED_INT, offsetof(Vertex, material));
  for (GLuint attribute = 0; attribute < 3; ++attribute) {
    glEnableVertexArrayAttrib(mesh.vertexArray, attribute);
    glVertexArrayAttribBinding(mesh.vertexArray, attribute, 0);
  }
  return mesh;
}

// The vertex shader layertrace links for its capture: this program's vertex layout, written to
// the outputs layertrace reads (GpuGeometry). The scene does not move, so the positions are
// passed as they are.
const char* const kCaptureVertexShader = R"(#version 450
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in uint material;
out vec3 ltPosition;
out vec3 ltNormal;
flat out uint ltMaterial;
void main() {
  ltPosition = position;
  ltNormal = normal;
  ltMaterial = material;
})";

// The program's own shading: a head-light Lambert term.
const char* const kShadeVertexShader = R"(#version 450
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
uniform mat4 uClip, uView;
out vec3 viewNormal;
void main() {
  viewNormal = mat3(uView) * normal;
  gl_Position = uClip * vec4(position, 1.0);
})";
const char* const kShadeFragmentShader = R"(#version 450
in vec3 viewNormal;
out vec4 colour;
void main() {
  const float lambert = abs(normalize(viewNormal).z);
  colour = vec4(vec3(0.1 + 0.8 * lambert), 1.0);
})";

// layertrace's picture on the screen: its row 0 is the picture's top.
const char* const kPresentVertexShader = R"(#version 450
out vec2 uv;
void main() {
  const vec2 corner = vec2(float((gl_VertexID & 1) << 2), float((gl_VertexID & 2) << 1));
  uv = vec2(corner.x * 0.5, 1.0 - corner.y * 0.5);
  gl_Position = vec4(corner - 1.0, 0.0, 1.0);
})";
const char* const kPresentFragmentShader = R"(#version 450
in vec2 uv;
uniform sampler2D uPicture;
out vec4 colour;
void main() { colour = texture(uPicture, uv); })";

GLuint linkProgram(const char* vertex, const char* fragment) {
  const GLuint program = glCreateProgram();
  for (const auto& [stage, source] : {std::pair{GL_VERTEX_SHADER, vertex}, std::pair{GL_FRAGMENT_SHADER, fragment}}) {
    const GLuint shader = glCreateShader(stage);
    glShaderSource(shader, 1, &source, nullptr);
    glCompileShader(shader);
    glAttachShader(program, shader);
    glDeleteShader(shader);
  }
  glLinkProgram(program);
  GLint linked = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &linked);
  if (!linked) throw std::runtime_error("a shader of gpu_reflections does not link");
  return program;
}

// The reflection frame: the draw call layertrace issues into its capture.
lt::GpuFrameInfo reflect(lt::GpuRenderer& renderer, const Mesh& mesh, const lt::View& view, GLuint picture) {
  lt::GpuEffectRequest reflection;
  reflection.effect = "reflection";
  return renderer.render(view, reflection, picture, [&](uint32_t) {
    glBindVertexArray(mesh.vertexArray);
    glDrawArrays(GL_TRIANGLES, 0, mesh.vertices);
  });
}

// One frame without a window: a surfaceless EGL context (Mesa's), the picture in an RGBA32F
// texture, read back as linear RGB and written as `layertrace render` writes its PNG.
int headless(const std::string& scenePath, const std::string& out, int width, int height) {
  const EGLDisplay display = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  EGLint major = 0, minor = 0;
  if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor) || !eglBindAPI(EGL_OPENGL_API))
    throw std::runtime_error("no surfaceless EGL display (Mesa's libegl-mesa0)");
  const EGLint attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5, EGL_CONTEXT_OPENGL_PROFILE_MASK,
                               EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  const EGLContext context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attributes);
  if (context == EGL_NO_CONTEXT || !eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context))
    throw std::runtime_error("no OpenGL 4.5 core context from EGL");
  {
    const lt::TriangleScene scene = lt::TriangleScene::load(scenePath);
    const lt::View view = scene.view("", width, height);
    const Mesh mesh = upload(scene);
    lt::GpuDevice device;
    lt::GpuRenderer renderer(device, scene, lt::GpuGeometry{kCaptureVertexShader, scene.triangleCount()});
    GLuint picture = 0;
    glCreateTextures(GL_TEXTURE_2D, 1, &picture);
    glTextureStorage2D(picture, 1, GL_RGBA32F, width, height);
    const lt::GpuFrameInfo info = reflect(renderer, mesh, view, picture);
    std::vector<float> rgba(size_t(width) * size_t(height) * 4);
    glGetTextureImage(picture, 0, GL_RGBA, GL_FLOAT, GLsizei(rgba.size() * sizeof(float)), rgba.data());
    lt::RgbImage image;
    image.width = width, image.height = height;
    for (size_t i = 0; i < rgba.size(); i += 4) image.rgb.insert(image.rgb.end(), {rgba[i], rgba[i + 1], rgba[i + 2]});
    image.savePng(out);
    std::printf("gpu_reflections: %s, %dx%d on %s: %llu triangles drawn, %llu fragments, %llu rays, %llu hits -> %s\n", scenePath.c_str(),
                width, height, device.renderer().c_str(), static_cast<unsigned long long>(info.triangles),
                static_cast<unsigned long long>(info.fragments), static_cast<unsigned long long>(info.rays),
                static_cast<unsigned long long>(info.hits), out.c_str());
    glDeleteTextures(1, &picture);
    glDeleteVertexArrays(1, &mesh.vertexArray);
    glDeleteBuffers(1, &mesh.buffer);
  }
  eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(display, context);
  eglTerminate(display);
  return 0;
}

#if GPU_REFLECTIONS_WINDOW
// The camera orbits the default view's target: the mouse turns it, the wheel moves it in and out.
struct Orbit {
  lt::View home;
  float yaw = 0.0f, pitch = 0.0f, zoom = 1.0f;
  double lastX = 0.0, lastY = 0.0;
  bool dragging = false, reflections = true;

  lt::View view(int width, int height) const {
    lt::View v = home;
    v.width = width, v.height = height;
    const glm::vec3 offset = home.eye - home.target;
    glm::mat4 turn = glm::rotate(glm::mat4(1.0f), yaw, home.up);
    turn = glm::rotate(turn, pitch, glm::normalize(glm::cross(offset, home.up)));
    v.eye = home.target + zoom * glm::vec3(turn * glm::vec4(offset, 0.0f));
    return v;
  }
};

int windowed(const std::string& scenePath) {
  if (!glfwInit()) throw std::runtime_error("GLFW cannot start (no display?)");
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  GLFWwindow* window = glfwCreateWindow(960, 540, "gpu_reflections", nullptr, nullptr);
  if (!window) throw std::runtime_error("no OpenGL 4.5 core window");
  glfwMakeContextCurrent(window);
  {
    const lt::TriangleScene scene = lt::TriangleScene::load(scenePath);
    Orbit orbit;
    orbit.home = scene.view("", 960, 540);
    glfwSetWindowUserPointer(window, &orbit);
    glfwSetMouseButtonCallback(window, [](GLFWwindow* w, int, int action, int) {
      static_cast<Orbit*>(glfwGetWindowUserPointer(w))->dragging = action == GLFW_PRESS;
    });
    glfwSetScrollCallback(window, [](GLFWwindow* w, double, double dy) {
      Orbit& o = *static_cast<Orbit*>(glfwGetWindowUserPointer(w));
      o.zoom = std::clamp(o.zoom * std::pow(0.9f, float(dy)), 0.05f, 20.0f);
    });
    glfwSetKeyCallback(window, [](GLFWwindow* w, int key, int, int action, int) {
      if (action != GLFW_PRESS) return;
      if (key == GLFW_KEY_SPACE) static_cast<Orbit*>(glfwGetWindowUserPointer(w))->reflections ^= true;
      if (key == GLFW_KEY_ESCAPE) glfwSetWindowShouldClose(w, 1);
    });
    const Mesh mesh = upload(scene);
    const GLuint shade = linkProgram(kShadeVertexShader, kShadeFragmentShader), present = linkProgram(kPresentVertexShader, kPresentFragmentShader);
    GLuint empty = 0, picture = 0;
    glCreateVertexArrays(1, &empty);
    int pictureWidth = 0, pictureHeight = 0;
    lt::GpuDevice device;
    lt::GpuRenderer renderer(device, scene, lt::GpuGeometry{kCaptureVertexShader, scene.triangleCount()});
    while (!glfwWindowShouldClose(window)) {
      glfwPollEvents();
      double x = 0.0, y = 0.0;
      glfwGetCursorPos(window, &x, &y);
      if (orbit.dragging) {
        orbit.yaw -= float(x - orbit.lastX) * 0.01f;
        orbit.pitch = std::clamp(orbit.pitch - float(y - orbit.lastY) * 0.01f, -1.2f, 1.2f);
      }
      orbit.lastX = x, orbit.lastY = y;
      int width = 0, height = 0;
      glfwGetFramebufferSize(window, &width, &height);
      if (width == 0 || height == 0) continue;
      const lt::View view = orbit.view(width, height);
      glViewport(0, 0, width, height);
      glClearColor(0.05f, 0.06f, 0.08f, 1.0f);
      glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
      if (orbit.reflections) {
        if (width != pictureWidth || height != pictureHeight) {
          glDeleteTextures(1, &picture);
          glCreateTextures(GL_TEXTURE_2D, 1, &picture);
          glTextureStorage2D(picture, 1, GL_RGBA8, width, height);  // the PNG's sRGB codes, shown as they are
          glTextureParameteri(picture, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
          glTextureParameteri(picture, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
          pictureWidth = width, pictureHeight = height;
        }
        reflect(renderer, mesh, view, picture);
        glUseProgram(present);
        glBindTextureUnit(0, picture);
        glBindVertexArray(empty);
        glDrawArrays(GL_TRIANGLES, 0, 3);
      } else {
        const glm::mat4 viewMatrix = glm::lookAt(view.eye, view.target, view.up);
        const glm::mat4 clip = glm::perspective(glm::radians(view.fovY), float(width) / float(height), view.near, view.far) * viewMatrix;
        glEnable(GL_DEPTH_TEST);
        glUseProgram(shade);
        glProgramUniformMatrix4fv(shade, glGetUniformLocation(shade, "uClip"), 1, GL_FALSE, &clip[0][0]);
        glProgramUniformMatrix4fv(shade, glGetUniformLocation(shade, "uView"), 1, GL_FALSE, &viewMatrix[0][0]);
        glBindVertexArray(mesh.vertexArray);
        glDrawArrays(GL_TRIANGLES, 0, mesh.vertices);
        glDisable(GL_DEPTH_TEST);
      }
      glfwSwapBuffers(window);
    }
    glDeleteTextures(1, &picture);
    glDeleteVertexArrays(1, &empty);
    glDeleteVertexArrays(1, &mesh.vertexArray);
    glDeleteBuffers(1, &mesh.buffer);
    glDeleteProgram(shade);
    glDeleteProgram(present);
  }
  glfwDestroyWindow(window);
  glfwTerminate();
  return 0;
}
#endif

}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc == 3 || argc == 5) {
      const int width = argc == 5 ? std::atoi(argv[3]) : 640, height = argc == 5 ? std::atoi(argv[4]) : 360;
      if (width < 1 || height < 1) throw std::invalid_argument("WIDTH and HEIGHT: must be positive integers");
      return headless(argv[1], argv[2], width, height);
    }
#if GPU_REFLECTIONS_WINDOW
    if (argc == 2) return windowed(argv[1]);
#endif
    std::fprintf(stderr, "usage: gpu_reflections SCENE OUT.png [WIDTH HEIGHT]%s\n",
                 GPU_REFLECTIONS_WINDOW ? "\n       gpu_reflections SCENE   (a window)" : "");
    return 2;
  } catch (const std::invalid_argument& e) {  // a scene, size or file the program cannot use
    std::fprintf(stderr, "gpu_reflections: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gpu_reflections: %s\n", e.what());
    return 1;
  }
}
