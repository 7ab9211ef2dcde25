#include "layertrace/gpu/gpu_context.h"

#include <dlfcn.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <string_view>
#include <utility>
#include <vector>

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include "layertrace/util/error.h"

namespace lt {

namespace {

/// A driver's log on one line: its lines joined by "; ", without the terminating NUL.
std::string oneLine(const std::string& log) {
  std::string out;
  for (char c : log) {
    if (c == '\0') break;
    if (c == '\n' || c == '\r') {
      if (!out.empty() && out.back() != ' ') out += "; ";
    } else {
      out += c;
    }
  }
  while (!out.empty() && (out.back() == ' ' || out.back() == ';')) out.pop_back();
  return out;
}

/// The process's GPU activity (gpuActivity); `submitted`: GPU work was issued since the last
/// blocking call, so the next one stalls.
struct Activity {
  std::atomic<uint64_t> links{0}, allocations{0}, upload{0}, download{0}, waits{0}, dispatches{0}, draws{0};
  std::atomic<bool> submitted{false};
} activity;

void noteSubmit() { activity.submitted.store(true, std::memory_order_relaxed); }
void noteBlockingCall() {
  if (activity.submitted.exchange(false, std::memory_order_relaxed)) activity.waits.fetch_add(1, std::memory_order_relaxed);
}
void noteDispatch() {
  activity.dispatches.fetch_add(1, std::memory_order_relaxed);
  noteSubmit();
}

[[noreturn]] void unavailable(const std::string& why) {
  inputError("--device gpu: no OpenGL 4.5 device (", why, ")");
}

std::string glString(GLenum name) {
  const auto* s = reinterpret_cast<const char*>(glGetString(name));
  return s ? s : "";
}

/// A display EGL offers, and what it is ("EGL device 0", "Mesa surfaceless").
struct Candidate {
  EGLDisplay display;
  std::string name;
};

/// The displays to try, in order: every hardware EGL device (NVIDIA's and Mesa's headless path),
/// then Mesa's surfaceless platform (llvmpipe on a machine without a GPU).
/// LAYERTRACE_GPU=software keeps only the software rasterizer even where a GPU is present.
std::vector<Candidate> candidateDisplays() {
  std::vector<Candidate> out;
  const char* want = std::getenv("LAYERTRACE_GPU");
  const bool softwareOnly = want && std::string_view(want) == "software";
  if (!softwareOnly && epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_EXT_device_enumeration") &&
      epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_EXT_platform_device")) {
    EGLDeviceEXT devices[16];
    EGLint count = 0;
    if (eglQueryDevicesEXT(16, devices, &count))
      for (EGLint i = 0; i < count; ++i) {
        const char* ext = eglQueryDeviceStringEXT(devices[i], EGL_EXTENSIONS);
        if (ext && std::string_view(ext).find("EGL_MESA_device_software") != std::string_view::npos) continue;
        if (EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr); d != EGL_NO_DISPLAY)
          out.push_back({d, cat("EGL device ", i)});
      }
  }
  if (epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_MESA_platform_surfaceless"))
    if (EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr); d != EGL_NO_DISPLAY)
      out.push_back({d, "Mesa surfaceless"});
  return out;
}

/// Whether an OpenGL context is current on this thread, made by EGL or by GLX (GLFW's default
/// under X11). GLX is asked only where the process has loaded it: layertrace links neither.
bool contextCurrent() {
  using GetCurrent = void* (*)();
  if (auto glx = reinterpret_cast<GetCurrent>(dlsym(RTLD_DEFAULT, "glXGetCurrentContext")); glx && glx()) return true;
  // A window library (GLFW, SDL) may load GLX privately (RTLD_LOCAL): ask its library.
  for (const char* library : {"libGLX.so.0", "libGL.so.1"})
    if (void* handle = dlopen(library, RTLD_LAZY | RTLD_LOCAL | RTLD_NOLOAD)) {
      auto glx = reinterpret_cast<GetCurrent>(dlsym(handle, "glXGetCurrentContext"));
      const bool current = glx && glx();
      dlclose(handle);
      if (current) return true;
    }
  if (void* egl = dlopen("libEGL.so.1", RTLD_LAZY | RTLD_LOCAL | RTLD_NOLOAD)) {
    dlclose(egl);
    return eglGetCurrentContext() != EGL_NO_CONTEXT;
  }
  return false;
}

}  // namespace

GpuActivity GpuActivity::operator-(const GpuActivity& b) const {
  return {programLinks - b.programLinks, bufferAllocations - b.bufferAllocations, uploadBytes - b.uploadBytes, downloadBytes - b.downloadBytes,
          hostWaits - b.hostWaits, dispatches - b.dispatches, draws - b.draws};
}

GpuActivity gpuActivity() {
  constexpr auto r = std::memory_order_relaxed;
  return {activity.links.load(r), activity.allocations.load(r), activity.upload.load(r), activity.download.load(r),
          activity.waits.load(r), activity.dispatches.load(r), activity.draws.load(r)};
}

void noteGpuDraw() {
  activity.draws.fetch_add(1, std::memory_order_relaxed);
  noteSubmit();
}

GpuDebugGroup::GpuDebugGroup(const char* name) { glPushDebugGroup(GL_DEBUG_SOURCE_APPLICATION, 0, -1, name); }
GpuDebugGroup::~GpuDebugGroup() { glPopDebugGroup(); }

GpuContext::GpuContext() {
  // libepoxy aborts the process when it cannot load libEGL: ask first.
  if (void* egl = dlopen("libEGL.so.1", RTLD_LAZY | RTLD_LOCAL)) dlclose(egl);
  else unavailable("libEGL.so.1 not found: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri");
  const std::vector<Candidate> candidates = candidateDisplays();
  if (candidates.empty()) unavailable("EGL offers no display: no driver for a headless context");
  // Each display in turn: the first that gives an OpenGL 4.5 core context is taken.
  std::string why;
  for (const Candidate& c : candidates) {
    const std::string failure = open(c.display);
    if (failure.empty()) {
      platform_ = c.name;
      return;
    }
    why += (why.empty() ? "" : "; ") + c.name + ": " + failure;
  }
  unavailable(why);
}

GpuContext::GpuContext(AdoptCurrent) : adopted_(true) {
  // epoxy resolves functions for whichever context is current (GLX or EGL): without one, no
  // GL call may be made at all.
  if (!contextCurrent())
    inputError("no OpenGL context is current on this thread (make yours current before creating layertrace's GPU objects)");
  version_ = glString(GL_VERSION);
  if (epoxy_gl_version() < 45) inputError("the current OpenGL context is ", version_.empty() ? "unknown" : version_, ": layertrace needs OpenGL 4.5");
  renderer_ = glString(GL_RENDERER);
  platform_ = "the caller's context";
}

GpuContext::GpuContext(ShareWith share) {
  const EGLContext previous = eglGetCurrentContext();
  const EGLSurface draw = eglGetCurrentSurface(EGL_DRAW), read = eglGetCurrentSurface(EGL_READ);
  const EGLDisplay previousDisplay = eglGetCurrentDisplay();
  const std::string failure = open(share.display, share.context);
  // The caller's context current again where it was (open made this one current).
  if (failure.empty()) release();
  if (previous != EGL_NO_CONTEXT) eglMakeCurrent(previousDisplay, draw, read, previous);
  if (!failure.empty()) unavailable("the window's EGL display: " + failure);
  platform_ = "shared with the caller's EGL context";
}

std::string GpuContext::open(void* candidate, void* shareContext) {
  auto display = static_cast<EGLDisplay>(candidate);
  EGLint major = 0, minor = 0;
  if (!eglInitialize(display, &major, &minor)) return cat("eglInitialize failed, EGL error ", eglGetError());
  // (no eglTerminate on failure: EGL hands every context on the same device the same display)
  if (!eglBindAPI(EGL_OPENGL_API)) return "the EGL driver has no desktop OpenGL";
  if (!epoxy_has_egl_extension(display, "EGL_KHR_surfaceless_context")) return "the EGL driver has no surfaceless contexts";
  EGLConfig config = EGL_NO_CONFIG_KHR;
  if (!epoxy_has_egl_extension(display, "EGL_KHR_no_config_context")) {
    const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(display, want, &config, 1, &n) || n < 1) return "no EGL configuration renders OpenGL";
  }
  const EGLint attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5, EGL_CONTEXT_OPENGL_PROFILE_MASK,
                               EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  EGLContext context = eglCreateContext(display, config, shareContext ? static_cast<EGLContext>(shareContext) : EGL_NO_CONTEXT, attributes);
  if (context == EGL_NO_CONTEXT) return "the driver offers no OpenGL 4.5 core context";
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    eglDestroyContext(display, context);
    return "eglMakeCurrent failed";
  }
  const std::string version = glString(GL_VERSION);
  if (epoxy_gl_version() < 45) {
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display, context);
    return "the context is OpenGL " + version;
  }
  display_ = display;
  context_ = context;
  renderer_ = glString(GL_RENDERER);
  version_ = version;
  return {};
}

GpuContext::~GpuContext() {
  if (adopted_) return;  // the caller's context, current: the cached programs are deleted in it
  if (!display_) return;
  auto display = static_cast<EGLDisplay>(display_);
  // The cached programs are deleted with their context current; where it is current on another
  // thread (the viewer's worker), they are left to the context's destruction, which frees them.
  if (context_ && eglGetCurrentContext() != static_cast<EGLContext>(context_))
    for (auto& entry : programs_) entry.second.forget();
  programs_.clear();
  release();
  if (context_) eglDestroyContext(display, static_cast<EGLContext>(context_));
  // No eglTerminate: EGL hands every context on the same device the same display, and
  // terminating it would end the other contexts of the process (the viewer's and a test's).
  // The display's connection lives until the process ends.
}

bool GpuContext::software() const {
  for (const char* name : {"llvmpipe", "softpipe", "SwiftShader"})
    if (renderer_.find(name) != std::string::npos) return true;
  return false;
}

void GpuContext::makeCurrent() const {
  if (adopted_ || eglGetCurrentContext() == static_cast<EGLContext>(context_)) return;
  if (!eglMakeCurrent(static_cast<EGLDisplay>(display_), EGL_NO_SURFACE, EGL_NO_SURFACE, static_cast<EGLContext>(context_)))
    throw InternalError("eglMakeCurrent failed (is the GPU context current on another thread?)");
}

void GpuContext::release() const {
  if (adopted_) return;
  if (eglGetCurrentContext() == static_cast<EGLContext>(context_))
    eglMakeCurrent(static_cast<EGLDisplay>(display_), EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
}

uint32_t GpuContext::link(std::string_view name, std::initializer_list<std::pair<uint32_t, std::string_view>> stages,
                          std::span<const char* const> varyings, bool callerSource) const {
  const auto fail = [&](const std::string& what) -> uint32_t {
    if (callerSource) throw InputError(what);
    throw InternalError(what);
  };
  auto log = [](GLuint object, bool program) {
    GLint n = 0;
    program ? glGetProgramiv(object, GL_INFO_LOG_LENGTH, &n) : glGetShaderiv(object, GL_INFO_LOG_LENGTH, &n);
    std::string s(size_t(std::max(n, 1)), '\0');
    program ? glGetProgramInfoLog(object, n, nullptr, s.data()) : glGetShaderInfoLog(object, n, nullptr, s.data());
    return s;
  };
  const GLuint program = glCreateProgram();
  std::vector<GLuint> shaders;
  for (const auto& [stage, source] : stages) {
    const GLuint shader = glCreateShader(stage);
    const GLchar* text = source.data();
    const GLint length = GLint(source.size());
    glShaderSource(shader, 1, &text, &length);
    glCompileShader(shader);
    GLint ok = 0;
    glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    shaders.push_back(shader);
    if (!ok) {
      const std::string why = log(shader, false);
      for (GLuint s : shaders) glDeleteShader(s);
      glDeleteProgram(program);
      return fail(cat("shader ", name, " does not compile on ", renderer_, ": ", oneLine(why)));
    }
    glAttachShader(program, shader);
  }
  if (!varyings.empty()) glTransformFeedbackVaryings(program, GLsizei(varyings.size()), varyings.data(), GL_SEPARATE_ATTRIBS);
  glLinkProgram(program);
  activity.links.fetch_add(1, std::memory_order_relaxed);
  for (GLuint s : shaders) glDeleteShader(s);
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    const std::string why = log(program, true);
    glDeleteProgram(program);
    return fail(cat("shader ", name, " does not link on ", renderer_, ": ", oneLine(why)));
  }
  return program;
}

const GpuProgram& GpuContext::computeProgram(std::string_view name, std::string_view source, std::string_view defines) const {
  std::string key = std::string(name) + "|" + std::string(defines);
  if (auto it = programs_.find(key); it != programs_.end()) return it->second;
  std::string variant;
  if (!defines.empty()) {
    // After the #version line, which must come first.
    const size_t line = source.find('\n');
    variant = std::string(source.substr(0, line + 1)) + std::string(defines) + std::string(source.substr(line + 1));
    source = variant;
  }
  return programs_.emplace(std::move(key), GpuProgram(link(name, {{GL_COMPUTE_SHADER, source}}))).first->second;
}

const GpuProgram& GpuContext::feedbackProgram(std::string_view vertex, std::span<const char* const> varyings) const {
  std::string key = "feedback|" + std::string(vertex);
  if (auto it = programs_.find(key); it != programs_.end()) return it->second;
  return programs_
      .emplace(std::move(key), GpuProgram(link("of the caller's geometry (vertex shader)", {{GL_VERTEX_SHADER, vertex}}, varyings, true)))
      .first->second;
}

const GpuProgram& GpuContext::renderProgram(std::string_view name, std::string_view vertex, std::string_view fragment) const {
  std::string key(name);
  if (auto it = programs_.find(key); it != programs_.end()) return it->second;
  return programs_.emplace(std::move(key), GpuProgram(link(name, {{GL_VERTEX_SHADER, vertex}, {GL_FRAGMENT_SHADER, fragment}}))).first->second;
}

bool GpuContext::hasExtension(std::string_view extension) const {
  if (extensions_.empty()) {
    // Read once, through entry points from EGL: epoxy's own check, and its first dispatch of
    // these, also probe GLX, which an EGL-only tracer (apitrace's egltrace) lacks.
    makeCurrent();
    const auto getStringi = reinterpret_cast<PFNGLGETSTRINGIPROC>(eglGetProcAddress("glGetStringi"));
    const auto getIntegerv = reinterpret_cast<PFNGLGETINTEGERVPROC>(eglGetProcAddress("glGetIntegerv"));
    GLint count = 0;
    if (getIntegerv) getIntegerv(GL_NUM_EXTENSIONS, &count);
    for (GLint i = 0; getStringi && i < count; ++i)
      if (const auto* name = reinterpret_cast<const char*>(getStringi(GL_EXTENSIONS, GLuint(i)))) extensions_.emplace_back(name);
    std::sort(extensions_.begin(), extensions_.end());
  }
  return std::binary_search(extensions_.begin(), extensions_.end(), extension, std::less<>());
}

void GpuContext::dispatch(const GpuProgram& program, size_t n) const {
  constexpr size_t kGroup = 64, kMaxGroups = 65535, perDispatch = kGroup * kMaxGroups;
  glUseProgram(program.id());
  for (size_t f = 0; f < n; f += perDispatch) {
    program.set("uFirst", int(f));
    glDispatchCompute(GLuint((std::min(perDispatch, n - f) + kGroup - 1) / kGroup), 1, 1);
    noteDispatch();
  }
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT);
}

void GpuContext::dispatchGroups(const GpuProgram& program, uint32_t groups) const {
  glUseProgram(program.id());
  program.set("uFirst", 0);
  glDispatchCompute(groups, 1, 1);
  noteDispatch();
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT);
}

void GpuContext::dispatchIndirect(const GpuProgram& program, const GpuBuffer& args, size_t offset) const {
  glUseProgram(program.id());
  program.set("uFirst", 0);
  glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, args.id());
  glDispatchComputeIndirect(GLintptr(offset));
  glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, 0);
  noteDispatch();
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT);
}

void GpuProgram::forget() { id_ = 0; }

GpuProgram::~GpuProgram() {
  if (id_) glDeleteProgram(id_);
}
GpuProgram::GpuProgram(GpuProgram&& other) noexcept : id_(std::exchange(other.id_, 0)) {}
GpuProgram& GpuProgram::operator=(GpuProgram&& other) noexcept {
  if (this != &other) {
    if (id_) glDeleteProgram(id_);
    id_ = std::exchange(other.id_, 0);
  }
  return *this;
}
void GpuProgram::set(const char* name, int v) const { glProgramUniform1i(id_, glGetUniformLocation(id_, name), v); }
void GpuProgram::set(const char* name, uint32_t v) const { glProgramUniform1ui(id_, glGetUniformLocation(id_, name), v); }
void GpuProgram::set(const char* name, float v) const { glProgramUniform1f(id_, glGetUniformLocation(id_, name), v); }
void GpuProgram::set(const char* name, const float* v, int count) const {
  glProgramUniform1fv(id_, glGetUniformLocation(id_, name), count, v);
}
void GpuProgram::setVec3(const char* name, const float* xyz, int count) const {
  glProgramUniform3fv(id_, glGetUniformLocation(id_, name), count, xyz);
}
void GpuProgram::setMatrix(const char* name, const float* columns, int count) const {
  glProgramUniformMatrix4fv(id_, glGetUniformLocation(id_, name), count, GL_FALSE, columns);
}
void GpuProgram::setIvec2(const char* name, const int* xy, int count) const {
  glProgramUniform2iv(id_, glGetUniformLocation(id_, name), count, xy);
}
void GpuProgram::setIvec3(const char* name, const int* xyz) const {
  glProgramUniform3iv(id_, glGetUniformLocation(id_, name), 1, xyz);
}
void GpuProgram::set(const char* name, const int* v, int count) const {
  glProgramUniform1iv(id_, glGetUniformLocation(id_, name), count, v);
}

GpuBuffer::GpuBuffer(size_t bytes, const void* data) : bytes_(std::max<size_t>(bytes, 16)) {
  glCreateBuffers(1, &id_);
  glNamedBufferStorage(id_, GLsizeiptr(bytes_), nullptr, GL_DYNAMIC_STORAGE_BIT);
  activity.allocations.fetch_add(1, std::memory_order_relaxed);
  if (glGetError() == GL_OUT_OF_MEMORY) {
    glDeleteBuffers(1, &id_);
    inputError("--device gpu: ", bytes_, " bytes of GPU memory are not available");
  }
  if (data && bytes > 0) write(data, bytes);
}

GpuBuffer GpuBuffer::borrowed(uint32_t id, size_t bytes) {
  GpuBuffer b;
  b.id_ = id, b.bytes_ = bytes, b.owned_ = false;
  return b;
}

GpuBuffer::~GpuBuffer() {
  if (id_ && owned_) glDeleteBuffers(1, &id_);
}

GpuBuffer::GpuBuffer(GpuBuffer&& other) noexcept
    : id_(std::exchange(other.id_, 0)), bytes_(std::exchange(other.bytes_, 0)), owned_(std::exchange(other.owned_, true)) {}

GpuBuffer& GpuBuffer::operator=(GpuBuffer&& other) noexcept {
  if (this != &other) {
    if (id_ && owned_) glDeleteBuffers(1, &id_);
    id_ = std::exchange(other.id_, 0);
    bytes_ = std::exchange(other.bytes_, 0);
    owned_ = std::exchange(other.owned_, true);
  }
  return *this;
}

GpuStateGuard::GpuStateGuard() {
  glGetIntegerv(GL_CURRENT_PROGRAM, &program_);
  glGetIntegerv(GL_VERTEX_ARRAY_BINDING, &vertexArray_);
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &drawFramebuffer_);
  glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &readFramebuffer_);
  glGetIntegerv(GL_VIEWPORT, viewport_);
  glGetIntegerv(GL_POLYGON_MODE, polygonMode_);
  for (size_t i = 0; i < kCapabilities.size(); ++i) enabled_[i] = glIsEnabled(kCapabilities[i]);
  glGetIntegerv(GL_SHADER_STORAGE_BUFFER_BINDING, &storage_);
  for (GLuint i = 0; i < kStorageBindings; ++i) {
    glGetIntegeri_v(GL_SHADER_STORAGE_BUFFER_BINDING, i, &storageIndexed_[i].buffer);
    glGetInteger64i_v(GL_SHADER_STORAGE_BUFFER_START, i, &storageIndexed_[i].offset);
    glGetInteger64i_v(GL_SHADER_STORAGE_BUFFER_SIZE, i, &storageIndexed_[i].size);
  }
  glGetIntegerv(GL_DISPATCH_INDIRECT_BUFFER_BINDING, &dispatchIndirect_);
  glGetIntegerv(GL_PIXEL_UNPACK_BUFFER_BINDING, &pixelUnpack_);
  glGetIntegerv(GL_TRANSFORM_FEEDBACK_BINDING, &transformFeedback_);
  glGetIntegerv(GL_ACTIVE_TEXTURE, &activeTexture_);
  for (GLuint unit = 0; unit < kTextureUnits; ++unit) {
    glActiveTexture(GL_TEXTURE0 + unit);
    glGetIntegerv(GL_TEXTURE_BINDING_2D, &texture2d_[unit]);
    glGetIntegerv(GL_SAMPLER_BINDING, &sampler_[unit]);
  }
  glActiveTexture(GLenum(activeTexture_));
  for (size_t i = 0; i < kUnpack.size(); ++i) glGetIntegerv(kUnpack[i], &unpack_[i]);
}

GpuStateGuard::~GpuStateGuard() {
  glUseProgram(GLuint(program_));
  glBindVertexArray(GLuint(vertexArray_));
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(drawFramebuffer_));
  glBindFramebuffer(GL_READ_FRAMEBUFFER, GLuint(readFramebuffer_));
  glViewport(viewport_[0], viewport_[1], viewport_[2], viewport_[3]);
  glPolygonMode(GL_FRONT_AND_BACK, GLenum(polygonMode_[0]));
  for (size_t i = 0; i < kCapabilities.size(); ++i) (enabled_[i] ? glEnable : glDisable)(kCapabilities[i]);
  for (GLuint i = 0; i < kStorageBindings; ++i) {
    const Binding& b = storageIndexed_[i];
    if (b.buffer != 0 && b.size > 0) glBindBufferRange(GL_SHADER_STORAGE_BUFFER, i, GLuint(b.buffer), GLintptr(b.offset), GLsizeiptr(b.size));
    else glBindBufferBase(GL_SHADER_STORAGE_BUFFER, i, GLuint(b.buffer));
  }
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, GLuint(storage_));
  glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, GLuint(dispatchIndirect_));
  glBindBuffer(GL_PIXEL_UNPACK_BUFFER, GLuint(pixelUnpack_));
  glBindTransformFeedback(GL_TRANSFORM_FEEDBACK, GLuint(transformFeedback_));
  for (GLuint unit = 0; unit < kTextureUnits; ++unit) {
    glActiveTexture(GL_TEXTURE0 + unit);
    glBindTexture(GL_TEXTURE_2D, GLuint(texture2d_[unit]));
    glBindSampler(unit, GLuint(sampler_[unit]));
  }
  glActiveTexture(GLenum(activeTexture_));
  for (size_t i = 0; i < kUnpack.size(); ++i) glPixelStorei(kUnpack[i], unpack_[i]);
}

void GpuBuffer::bindStorage(uint32_t index) const { glBindBufferBase(GL_SHADER_STORAGE_BUFFER, index, id_); }

void GpuBuffer::write(const void* data, size_t bytes, size_t offset) const {
  LT_CHECK(offset + bytes <= bytes_, offset, bytes, bytes_);
  glNamedBufferSubData(id_, GLintptr(offset), GLsizeiptr(bytes), data);
  activity.upload.fetch_add(bytes, std::memory_order_relaxed);
}

void GpuBuffer::fill(uint32_t value) const { glClearNamedBufferData(id_, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &value); }

void GpuBuffer::read(void* data, size_t bytes, size_t offset) const {
  LT_CHECK(offset + bytes <= bytes_, offset, bytes, bytes_);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  noteBlockingCall();
  glGetNamedBufferSubData(id_, GLintptr(offset), GLsizeiptr(bytes), data);
  activity.download.fetch_add(bytes, std::memory_order_relaxed);
}

GpuTimer::GpuTimer() { glCreateQueries(GL_TIMESTAMP, 2, ids_); }
GpuTimer::~GpuTimer() { glDeleteQueries(2, ids_); }
void GpuTimer::begin() const { glQueryCounter(ids_[0], GL_TIMESTAMP); }
void GpuTimer::end() const { glQueryCounter(ids_[1], GL_TIMESTAMP); }
double GpuTimer::ms() const {
  GLuint64 t0 = 0, t1 = 0;
  noteBlockingCall();
  glGetQueryObjectui64v(ids_[0], GL_QUERY_RESULT, &t0);
  glGetQueryObjectui64v(ids_[1], GL_QUERY_RESULT, &t1);
  return t1 > t0 ? double(t1 - t0) * 1e-6 : 0.0;
}

GpuTimeline::~GpuTimeline() {
  if (!pool_.empty()) glDeleteQueries(GLsizei(pool_.size()), pool_.data());
}

uint32_t GpuTimeline::query() {
  if (used_ == pool_.size()) {
    GLuint id = 0;
    glCreateQueries(GL_TIMESTAMP, 1, &id);
    pool_.push_back(id);
  }
  return pool_[used_++];
}

void GpuTimeline::begin(int stage) {
  spans_.emplace_back(stage, used_);
  glQueryCounter(query(), GL_TIMESTAMP);
}

void GpuTimeline::end(int) { glQueryCounter(query(), GL_TIMESTAMP); }

std::vector<double> GpuTimeline::collect(int n) {
  std::vector<double> ms(size_t(std::max(n, 0)), 0.0);
  if (!spans_.empty()) noteBlockingCall();
  for (const auto& [stage, first] : spans_) {
    GLuint64 t0 = 0, t1 = 0;
    glGetQueryObjectui64v(pool_[first], GL_QUERY_RESULT, &t0);
    glGetQueryObjectui64v(pool_[first + 1], GL_QUERY_RESULT, &t1);
    if (stage >= 0 && stage < n && t1 > t0) ms[size_t(stage)] += double(t1 - t0) * 1e-6;
  }
  spans_.clear();
  used_ = 0;
  return ms;
}

}  // namespace lt
