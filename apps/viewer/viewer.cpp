// `layertrace view`: the interactive viewer. A GLFW window with an OpenGL 3.3 core
// context shows the CPU pipeline's picture as a texture behind a Dear ImGui panel; a worker
// thread renders (ViewSession, app/view_session.h) while the UI keeps drawing, the newest
// request replacing any older one that has not started. While the camera moves the worker
// traces at half width and height (¼ of the pixels); when it stops the full picture follows.
//
// Scripted mode (--frames N): N full-resolution frames without input, then --screenshot writes
// the last traced image exactly as `render` would and --screenshot-ui the whole window.
#include <GLFW/glfw3.h>  // includes the system's GL/gl.h: the GL 1.1 calls used here are exported by libGL
#if LAYERTRACE_HAS_GPU
#define GLFW_EXPOSE_NATIVE_EGL
#include <GLFW/glfw3native.h>  // glfwGetEGLDisplay, glfwGetEGLContext: the GPU context shares the window's objects
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtx/rotate_vector.hpp>
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include "layertrace/app/cli.h"
#include "layertrace/app/view_session.h"
#include "layertrace/eval/classify.h"
#include "layertrace/util/error.h"

namespace lt {

namespace {

using Clock = std::chrono::steady_clock;

/// Renders requests on its own thread: the UI never waits for a picture. submit() replaces a
/// request that has not started (the newest camera wins); take() returns a finished one.
class Worker {
 public:
  explicit Worker(ViewSession& session) : session_(session), thread_([this] { loop(); }) {}
  ~Worker() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      quit_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  void submit(const ViewRequest& r) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      pending_ = r;
    }
    cv_.notify_all();
  }
  std::optional<ViewResult> take() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::optional<ViewResult> r = std::move(done_);
    done_.reset();
    return r;
  }
  /// Blocks until the worker has nothing pending or running (scripted mode).
  void wait() {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return !pending_ && !busy_; });
  }
  /// Nothing to do and nothing undelivered: a picture left on the GPU (ViewResult::gpuPicture)
  /// is rewritten by the next render, so the next request waits until this one was taken.
  bool idle() {
    std::lock_guard<std::mutex> lock(mutex_);
    return !pending_ && !busy_ && !done_;
  }

 private:
  void loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      cv_.wait(lock, [this] { return quit_ || pending_; });
      if (quit_) return;
      const ViewRequest r = *pending_;
      pending_.reset();
      busy_ = true;
      lock.unlock();
      ViewResult result = session_.render(r);
      lock.lock();
      done_ = std::move(result);
      busy_ = false;
      cv_.notify_all();
    }
  }
  ViewSession& session_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::optional<ViewRequest> pending_;
  std::optional<ViewResult> done_;
  bool busy_ = false, quit_ = false;
  std::thread thread_;  // last: started after the members it uses
};

/// The fly camera: position and view direction, turned about the camera's own up vector (the
/// scene's up, whatever axis that is) and its right vector.
struct FlyCamera {
  glm::vec3 eye{0.0f}, forward{0.0f, 0.0f, -1.0f}, up{0.0f, 1.0f, 0.0f};
  float distance = 1.0f;
  std::string name;

  static FlyCamera from(const CameraDesc& d) {
    FlyCamera c;
    c.eye = d.eye;
    c.forward = glm::normalize(d.target - d.eye);
    c.up = glm::normalize(d.up);
    c.distance = glm::length(d.target - d.eye);
    c.name = d.name;
    return c;
  }
  glm::vec3 right() const { return glm::normalize(glm::cross(forward, up)); }
  /// Yaw about `up`, pitch about `right`, never past 85° from the up axis.
  void turn(float yaw, float pitch) {
    forward = glm::normalize(glm::rotate(forward, -yaw, up));
    const glm::vec3 f = glm::normalize(glm::rotate(forward, -pitch, right()));
    if (std::abs(glm::dot(f, up)) < 0.996f) forward = f;
  }
  CameraDesc desc(const CameraDesc& base) const {
    CameraDesc d = base;
    d.eye = eye;
    d.target = eye + forward * distance;
    d.name = name;
    return d;
  }
};

std::vector<std::string> registeredTracers() {
  std::vector<std::string> names;
  for (const lt::TracerEntry& e : lt::tracerRegistry()) names.push_back(e.info.name);
  return names;
}

void uploadTexture(unsigned texture, const Image& image, std::vector<uint8_t>& bytes) {
  encode8(image, true, 3, bytes);  // the bytes `render` writes to its PNG
  glBindTexture(GL_TEXTURE_2D, texture);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB, image.width, image.height, 0, GL_RGB, GL_UNSIGNED_BYTE, bytes.data());
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
}

/// The picture the GPU left in a buffer shared with this context (ViewResult::gpuPicture: RGBA8
/// sRGB codes, rows from the top) into `texture`, copied on the GPU (a pixel-unpack buffer), then
/// waited for, since the next picture is drawn into the same buffer by the other context.
void copyGpuPicture(unsigned texture, const ViewResult& r) {
  static const auto bindBuffer = reinterpret_cast<PFNGLBINDBUFFERPROC>(glfwGetProcAddress("glBindBuffer"));
  bindBuffer(GL_PIXEL_UNPACK_BUFFER, r.gpuPicture);
  glBindTexture(GL_TEXTURE_2D, texture);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, r.pictureWidth, r.pictureHeight, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
  bindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glFinish();
}

void writeWindow(const std::string& path, int width, int height) {
  std::vector<uint8_t> pixels(size_t(width) * size_t(height) * 3), flipped(pixels.size());
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadBuffer(GL_BACK);
  glReadPixels(0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, pixels.data());
  const size_t row = size_t(width) * 3;
  for (int y = 0; y < height; ++y) std::copy_n(&pixels[size_t(height - 1 - y) * row], row, &flipped[size_t(y) * row]);
  writePngBytes(path, width, height, 3, flipped.data());
}

/// The panel: every option of the request, the statistics of the shown picture.
/// Returns true when an option changed (the picture must be redone).
bool panel(ViewRequest& q, FlyCamera& cam, const std::vector<CameraDesc>& cameras, const ViewResult* shown, double frameMs,
           const std::vector<std::string>& tracers) {
  bool changed = false;
  ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.8f);
  ImGui::Begin("layertrace", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
  ImGui::Text("UI %.1f ms/frame (%.0f fps)", frameMs, frameMs > 0.0 ? 1000.0 / frameMs : 0.0);
  if (shown) {
    if (!shown->error.empty()) ImGui::TextColored(ImVec4(1, 0.4f, 0.4f, 1), "%s", shown->error.c_str());
    ImGui::Text("%dx%d%s: capture %.1f, structure %.1f, trace %.1f (%s), shade %.1f ms (%s)",
                shown->gpuPicture ? shown->pictureWidth : shown->image.width, shown->gpuPicture ? shown->pictureHeight : shown->image.height,
                shown->scale > 1 ? " (moving)" : "", shown->captureMs, shown->structureMs, shown->traceMs, shown->device.c_str(),
                shown->shadeMs, shown->shading.c_str());
    ImGui::Text("picture %.0f ms, %.2f MRays/s", shown->totalMs, shown->traceMs > 0.0 ? double(shown->rays) / shown->traceMs / 1000.0 : 0.0);
    if (shown->gpuFrame.is_object() && !shown->gpuFrame.empty()) {
      const nlohmann::json& g = shown->gpuFrame;
      ImGui::Text("GPU frame: %.1f MB up, %.1f MB down, %d waits, %d links, %d allocations, %d dispatches, %d draws",
                  g.value("upload_bytes", 0.0) / 1e6, g.value("download_bytes", 0.0) / 1e6, g.value("host_waits", 0), g.value("program_links", 0),
                  g.value("buffer_allocations", 0), g.value("dispatches", 0), g.value("draws", 0));
    }
    if (shown->iterationsMean > 0.0) ImGui::Text("%.1f iterations/ray", shown->iterationsMean);
  }
  ImGui::Separator();
  int t = int(std::find(tracers.begin(), tracers.end(), q.tracer) - tracers.begin());
  if (ImGui::BeginCombo("tracer", q.tracer.c_str())) {
    for (size_t i = 0; i < tracers.size(); ++i)
      if (ImGui::Selectable(tracers[i].c_str(), int(i) == t)) q.tracer = tracers[i], changed = true;
    ImGui::EndCombo();
  }
  static const Effect effects[] = {Effect::Shade, Effect::Reflection, Effect::Refraction, Effect::AO, Effect::Shadow};
  if (ImGui::BeginCombo("effect", effectName(q.effect.effect))) {
    for (Effect e : effects)
      if (ImGui::Selectable(effectName(e), e == q.effect.effect)) q.effect.effect = e, changed = true;
    ImGui::EndCombo();
  }
  changed |= ImGui::SliderInt("bounces", &q.effect.bounces, 1, 4);
  changed |= ImGui::SliderInt("k (layers)", &q.layers, 1, 8);
  changed |= ImGui::SliderFloat("thickness (px)", &q.thicknessPx, 0.5f, 20.0f, "%.1f");
  changed |= ImGui::SliderFloat("tau", &q.tracers.pyramid.tau, 1.0f, 128.0f, "%.0f", ImGuiSliderFlags_Logarithmic);
  changed |= ImGui::SliderInt("levels", &q.tracers.pyramid.levels, 1, 8);
  changed |= ImGui::SliderInt("n_up", &q.tracers.hssr.nUp, 1, 4);
  changed |= ImGui::SliderFloat("ssr stride", &q.tracers.ssr.stride, 1.0f, 8.0f, "%.0f");
  int overlay = int(q.overlay);
  if (ImGui::Combo("overlay", &overlay, kViewOverlayNames, IM_ARRAYSIZE(kViewOverlayNames))) q.overlay = ViewOverlay(overlay), changed = true;
  if (q.overlay == ViewOverlay::Layer) changed |= ImGui::SliderInt("layer", &q.layer, 0, q.layers - 1);
  if (shown && shown->classified) {
    for (int i = 0; i < kRayClasses; ++i) {
      const glm::vec3 c = rayClassColor(RayClass(i));
      ImGui::PushID(i);
      ImGui::ColorButton("##legend", ImVec4(c.x, c.y, c.z, 1.0f), ImGuiColorEditFlags_NoTooltip, ImVec2(12, 12));
      ImGui::PopID();
      ImGui::SameLine();
      ImGui::Text("%-20s %6.2f %%", rayClassName(RayClass(i)), 100.0 * shown->classFractions[size_t(i)]);
    }
  }
  ImGui::Separator();
  if (!cameras.empty() && ImGui::BeginCombo("camera", cam.name.c_str())) {
    for (const CameraDesc& d : cameras)
      if (ImGui::Selectable(d.name.c_str(), d.name == cam.name)) cam = FlyCamera::from(d), q.camera = d, changed = true;
    ImGui::EndCombo();
  }
  ImGui::TextDisabled("WASD move, Q/E down/up, right mouse drag: look, shift: faster, H: hide this panel");
  ImGui::End();
  return changed;
}

/// Keyboard and mouse → camera motion; true if the camera moved this frame.
bool fly(GLFWwindow* window, FlyCamera& cam, float speed, float dt, double& lastX, double& lastY, bool& dragging) {
  const ImGuiIO& io = ImGui::GetIO();
  bool moved = false;
  if (!io.WantCaptureKeyboard) {
    glm::vec3 v(0.0f);
    if (glfwGetKey(window, GLFW_KEY_W) == GLFW_PRESS) v += cam.forward;
    if (glfwGetKey(window, GLFW_KEY_S) == GLFW_PRESS) v -= cam.forward;
    if (glfwGetKey(window, GLFW_KEY_D) == GLFW_PRESS) v += cam.right();
    if (glfwGetKey(window, GLFW_KEY_A) == GLFW_PRESS) v -= cam.right();
    if (glfwGetKey(window, GLFW_KEY_E) == GLFW_PRESS) v += cam.up;
    if (glfwGetKey(window, GLFW_KEY_Q) == GLFW_PRESS) v -= cam.up;
    if (glm::length(v) > 0.0f) {
      const float boost = glfwGetKey(window, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ? 4.0f : 1.0f;
      cam.eye += glm::normalize(v) * speed * boost * dt;
      moved = true;
    }
  }
  double x, y;
  glfwGetCursorPos(window, &x, &y);
  const bool down = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS && !io.WantCaptureMouse;
  if (down && dragging && (x != lastX || y != lastY)) {
    cam.turn(float(x - lastX) * 0.004f, float(y - lastY) * 0.004f);
    moved = true;
  }
  dragging = down, lastX = x, lastY = y;
  return moved;
}

}  // namespace

int runViewer(const ViewOptions& o) {
  validateViewOptions(o);
  for (const std::string* path : {&o.screenshot, &o.screenshotUi})
    if (std::filesystem::path(*path).has_parent_path()) ensureDirectory(std::filesystem::path(*path).parent_path().string(), "--screenshot");
  ViewSession session(o.render);
  ViewRequest request = session.initialRequest();
  request.overlay = parseViewOverlay(o.overlay);
  const bool scripted = o.frames > 0;
  if (!glfwInit()) inputError("view: cannot open a window (no display? scripted runs work under xvfb-run)");
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_RESIZABLE, scripted ? GLFW_FALSE : GLFW_TRUE);
  // --device gpu: the window's context through EGL, so that the GPU's context can share its
  // buffers and the picture is shown where it was computed; GLX where EGL gives no window.
  const bool gpu = o.render.run.device == "gpu";
#if LAYERTRACE_HAS_GPU
  if (gpu) glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_EGL_CONTEXT_API);
#endif
  GLFWwindow* window = glfwCreateWindow(request.width, request.height, "layertrace view", nullptr, nullptr);
  if (!window && gpu) {
    glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_NATIVE_CONTEXT_API);
    window = glfwCreateWindow(request.width, request.height, "layertrace view", nullptr, nullptr);
  }
  if (!window) {
    glfwTerminate();
    inputError("view: cannot create an OpenGL 3.3 core window (no display or no GL 3.3? scripted runs work under xvfb-run)");
  }
  glfwMakeContextCurrent(window);
#if LAYERTRACE_HAS_GPU
  if (gpu && glfwGetWindowAttrib(window, GLFW_CONTEXT_CREATION_API) == GLFW_EGL_CONTEXT_API) {
    const std::string why = session.presentOnGpu(glfwGetEGLDisplay(), glfwGetEGLContext(window));
    glfwMakeContextCurrent(window);
    if (!why.empty() && !o.render.run.quiet) std::fprintf(stderr, "view: the picture is read back from the GPU (%s)\n", why.c_str());
  }
#endif
  // The picture stays on the GPU unless a scripted run writes it to a file.
  request.pictureOnGpu = session.presentsOnGpu() && o.screenshot.empty();
  glfwSwapInterval(scripted ? 0 : 1);
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini in the user's folder
  ImGui::StyleColorsDark();
  ImGui_ImplGlfw_InitForOpenGL(window, true);
  ImGui_ImplOpenGL3_Init("#version 330 core");

  unsigned texture = 0;
  glGenTextures(1, &texture);
  std::vector<uint8_t> bytes;  // reused for every upload
  std::optional<ViewResult> shown;
  const std::vector<std::string> tracers = registeredTracers();
  std::vector<CameraDesc> cameras = session.frame().scene.cameras;
  cameras.insert(cameras.begin(), request.camera);
  cameras.front().name = request.camera.name.empty() ? "start" : request.camera.name;
  FlyCamera cam = FlyCamera::from(cameras.front());
  const float speed = 0.15f * session.frame().scene.bounds().diagonal();  // scene units per second
  double lastX = 0.0, lastY = 0.0;
  bool dragging = false, dirty = true, showPanel = !o.hidePanel, hWasDown = false;
  auto lastMove = Clock::now() - std::chrono::seconds(1), lastFrame = Clock::now();
  int status = 0;
  {
    Worker worker(session);
    for (int frame = 0; !glfwWindowShouldClose(window); ++frame) {
      glfwPollEvents();
      const auto now = Clock::now();
      const double frameMs = std::chrono::duration<double, std::milli>(now - lastFrame).count();
      lastFrame = now;
      if (scripted) {
        // One full picture per frame, waited for: the traced image is `render`'s.
        request.scale = 1;
        worker.submit(request);
        worker.wait();
      }
      if (std::optional<ViewResult> r = worker.take()) {
        if (r->gpuPicture) copyGpuPicture(texture, *r);
        else if (!r->image.data.empty()) uploadTexture(texture, r->image, bytes);
        shown = std::move(r);
      }
      ImGui_ImplOpenGL3_NewFrame();
      ImGui_ImplGlfw_NewFrame();
      ImGui::NewFrame();
      if (!scripted) {
        // The request keeps the scene's camera bit for bit until the user moves it.
        if (fly(window, cam, speed, float(frameMs) * 1e-3f, lastX, lastY, dragging))
          lastMove = now, dirty = true, request.camera = cam.desc(request.camera);
        const bool moving = now - lastMove < std::chrono::milliseconds(200);
        // While moving: ¼ of the pixels whenever the worker is free; once stopped: the full
        // picture if what is shown is reduced or out of date.
        if (worker.idle() && (dirty || (!moving && shown && shown->scale != 1))) {
          request.scale = moving ? 2 : 1;
          worker.submit(request);
          dirty = false;
        }
      }
      int fbw, fbh;
      glfwGetFramebufferSize(window, &fbw, &fbh);
      if (shown && (shown->gpuPicture || !shown->image.data.empty()))
        ImGui::GetBackgroundDrawList()->AddImage(reinterpret_cast<ImTextureID>(static_cast<intptr_t>(texture)), ImVec2(0, 0),
                                                 ImGui::GetIO().DisplaySize);
      const bool hDown = glfwGetKey(window, GLFW_KEY_H) == GLFW_PRESS;
      if (hDown && !hWasDown && !ImGui::GetIO().WantCaptureKeyboard) showPanel = !showPanel;
      hWasDown = hDown;
      if (showPanel && panel(request, cam, cameras, shown ? &*shown : nullptr, frameMs, tracers)) dirty = true;
      ImGui::Render();
      glViewport(0, 0, fbw, fbh);
      glClearColor(0.1f, 0.1f, 0.1f, 1.0f);
      glClear(GL_COLOR_BUFFER_BIT);
      ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
      if (scripted && frame + 1 == o.frames) {
        if (shown && !shown->error.empty()) {
          std::fprintf(stderr, "layertrace: %s\n", shown->error.c_str());
          status = 2;
        } else {
          if (!o.screenshotUi.empty()) writeWindow(o.screenshotUi, fbw, fbh);
          if (!o.screenshot.empty() && shown) writeImage(o.screenshot, shown->traced);
          if (!o.render.run.quiet && shown) {
            std::printf("view: %d frames, last %dx%d: capture %.1f ms, structure %.1f ms, trace %.1f ms (%s), shade %.1f ms (%s), picture %.1f ms",
                        o.frames, shown->gpuPicture ? shown->pictureWidth : shown->traced.width,
                        shown->gpuPicture ? shown->pictureHeight : shown->traced.height, shown->captureMs, shown->structureMs, shown->traceMs,
                        shown->device.c_str(), shown->shadeMs, shown->shading.c_str(), shown->totalMs);
            if (shown->gpuFrame.is_object() && !shown->gpuFrame.empty())
              std::printf("; GPU frame: %.0f B up, %.0f B down, %d waits, picture %s", shown->gpuFrame.value("upload_bytes", 0.0),
                          shown->gpuFrame.value("download_bytes", 0.0), shown->gpuFrame.value("host_waits", 0),
                          shown->gpuPicture ? "shown from the GPU" : "read back");
            std::printf("\n");
          }
        }
        glfwSwapBuffers(window);
        break;
      }
      glfwSwapBuffers(window);
    }
  }
  glDeleteTextures(1, &texture);
  session.closeGpu();  // before GLFW closes the EGL display a shared context uses
  glfwMakeContextCurrent(window);
  ImGui_ImplOpenGL3_Shutdown();
  ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
  glfwDestroyWindow(window);
  glfwTerminate();
  return status;
}

}  // namespace lt
