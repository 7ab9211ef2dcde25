// The GPU back end's one owner of OpenGL state: a headless OpenGL 4.5 core context through EGL
// (no window, no X server), the buffers shaders read and write, compute programs and timer
// queries. Function loading goes through libepoxy; any driver with OpenGL 4.5 serves (NVIDIA,
// AMD, Intel, Mesa's llvmpipe). Everything here runs on the thread that made the context
// current: GPU work is issued from one thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <span>
#include <string_view>
#include <initializer_list>
#include <map>
#include <utility>
#include <vector>

namespace lt {

class GpuBuffer;

/// A linked program, deleted with the object, and its uniforms by name (a name the compiler
/// dropped as unused is ignored, as OpenGL ignores location −1).
class GpuProgram {
 public:
  GpuProgram() = default;
  explicit GpuProgram(uint32_t id) : id_(id) {}
  ~GpuProgram();
  GpuProgram(GpuProgram&& other) noexcept;
  GpuProgram& operator=(GpuProgram&& other) noexcept;
  GpuProgram(const GpuProgram&) = delete;
  GpuProgram& operator=(const GpuProgram&) = delete;

  uint32_t id() const { return id_; }
  /// Drops the id without deleting the program (its context frees it when destroyed).
  void forget();
  void set(const char* name, int v) const;
  void set(const char* name, uint32_t v) const;
  void set(const char* name, float v) const;
  void setMatrix(const char* name, const float* columns, int count = 1) const;  ///< 4×4 matrices, 16 floats column-major each
  void setIvec2(const char* name, const int* xy, int count) const;  ///< an ivec2 array, 2 ints each
  void setIvec3(const char* name, const int* xyz) const;  ///< an ivec3
  void set(const char* name, const int* v, int count) const;  ///< an int array
  void set(const char* name, const float* v, int count) const;  ///< a float array
  void setVec3(const char* name, const float* xyz, int count = 1) const;  ///< a vec3 (array), 3 floats each

 private:
  uint32_t id_ = 0;
};

/// What the process has asked of the GPU so far, over all contexts: the frame accounting
/// (stats key gpu.frame) takes the difference of two readings. The same calls an apitrace dump
/// shows: a host wait is a blocking call (a buffer read, a timer read) after new GPU work was
/// submitted; blocking calls before the next submission cost no new stall.
struct GpuActivity {
  uint64_t programLinks = 0;       ///< programs linked (glLinkProgram)
  uint64_t bufferAllocations = 0;  ///< buffer objects given storage
  uint64_t uploadBytes = 0;        ///< bytes written into buffers from the host
  uint64_t downloadBytes = 0;      ///< bytes read back from buffers
  uint64_t hostWaits = 0;          ///< times the host stalled on the GPU
  uint64_t dispatches = 0;         ///< compute dispatches (direct and indirect)
  uint64_t draws = 0;              ///< draw calls
  GpuActivity operator-(const GpuActivity& before) const;
};
/// The activity so far.
GpuActivity gpuActivity();
/// Records a draw call issued outside GpuContext (the capture's geometry passes).
void noteGpuDraw();

/// A KHR_debug group around the passes of one stage ("capture", "hssr march", …): apitrace,
/// RenderDoc and Nsight show a frame's structure by these names.
class GpuDebugGroup {
 public:
  explicit GpuDebugGroup(const char* name);
  ~GpuDebugGroup();
  GpuDebugGroup(const GpuDebugGroup&) = delete;
  GpuDebugGroup& operator=(const GpuDebugGroup&) = delete;
};

class GpuContext {
 public:
  /// Opens the first OpenGL 4.5 device EGL offers, trying in turn every hardware EGL device
  /// (NVIDIA's headless path), then Mesa's surfaceless platform (llvmpipe). Throws InputError
  /// naming `--device gpu` and each display's reason when none gives a context.
  GpuContext();
  /// Adopts the OpenGL context current on the calling thread (a renderer's own: GLFW's, Qt's,
  /// an EGL context of the caller), which must be 4.5 or newer; layertrace then creates no
  /// context and never changes which one is current (makeCurrent and release do nothing). The
  /// caller keeps it current on this thread while the object and everything made with it live.
  /// InputError naming the version when it is older or none is current.
  struct AdoptCurrent {};
  explicit GpuContext(AdoptCurrent);
  /// A context of layertrace's own on the caller's EGL display that shares its objects (buffers,
  /// textures) with the caller's EGL context, so that a window draws what the GPU computed
  /// without a read-back (the viewer presents the resident frame's picture this way). The
  /// caller's context stays current where it is; this one is made current by makeCurrent, on
  /// whichever thread renders. InputError with the reason where the display gives none.
  struct ShareWith {
    void* display;  ///< EGLDisplay
    void* context;  ///< EGLContext
  };
  explicit GpuContext(ShareWith share);
  ~GpuContext();
  GpuContext(const GpuContext&) = delete;
  GpuContext& operator=(const GpuContext&) = delete;

  /// "NVIDIA H100 …", "llvmpipe (LLVM 15.0.6, 256 bits)".
  const std::string& renderer() const { return renderer_; }
  /// "4.5 (Core Profile) Mesa 22.3.6".
  const std::string& version() const { return version_; }
  /// The display taken: "EGL device 0", "Mesa surfaceless", or "the caller's context".
  const std::string& platform() const { return platform_; }
  /// True for a CPU rasterizer (llvmpipe, softpipe, SwiftShader): its timings are CPU timings.
  bool software() const;
  /// Makes the context current on the calling thread (it is after construction).
  void makeCurrent() const;
  /// Releases the context from the calling thread (when it is current there), so that another
  /// thread can make it current.
  void release() const;
  /// The compute program of shader `name`, compiled and linked on its first request and kept
  /// for the context's life (a program cache: a frame links nothing). `defines` ("#define X\n"
  /// lines, inserted after the #version line) make a variant of its own. Uniforms are per
  /// program, so a caller sets every uniform it relies on before each dispatch. InternalError
  /// with the driver's log on failure (the build validated every shader, so a failure here is a
  /// driver's).
  const GpuProgram& computeProgram(std::string_view name, std::string_view source, std::string_view defines = {}) const;
  /// The same for a vertex and a fragment shader linked together.
  const GpuProgram& renderProgram(std::string_view name, std::string_view vertex, std::string_view fragment) const;
  /// A caller's vertex shader (GLSL 4.50, its #version line included) linked alone, with the
  /// outputs `varyings` captured by transform feedback into separate buffers, in that order (the
  /// geometry a caller's draw calls give the capture, layertrace/gpu.h). Cached by its source.
  /// InputError with the driver's log when the source does not compile or link: it is the
  /// caller's, not layertrace's.
  const GpuProgram& feedbackProgram(std::string_view vertex, std::span<const char* const> varyings) const;
  /// Runs `program` (a compute shader of local size 64 whose invocation i handles item
  /// uFirst + gl_GlobalInvocationID.x) over `n` items, in dispatches the smallest OpenGL 4.5
  /// limit allows, then makes its buffer writes visible to the next commands.
  void dispatch(const GpuProgram& program, size_t n) const;
  /// Runs `program` over `groups` work groups, then a barrier for its buffer writes.
  void dispatchGroups(const GpuProgram& program, uint32_t groups) const;
  /// Runs `program` over the work groups that the device wrote into `args` at `offset` (three
  /// uints, glDispatchComputeIndirect), then a barrier for its buffer writes.
  void dispatchIndirect(const GpuProgram& program, const GpuBuffer& args, size_t offset = 0) const;
  /// Whether the driver offers `extension` (GL_ARB_shader_ballot, …).
  bool hasExtension(std::string_view extension) const;

 private:
  void* display_ = nullptr;
  void* context_ = nullptr;
  bool adopted_ = false;  ///< the caller's context (AdoptCurrent): not ours to make current or destroy
  /// Compiles and links `stages`, capturing `varyings` (separate buffers) when there are any;
  /// InternalError on failure, InputError where `callerSource` (the source is the caller's).
  uint32_t link(std::string_view name, std::initializer_list<std::pair<uint32_t, std::string_view>> stages,
                std::span<const char* const> varyings = {}, bool callerSource = false) const;
  /// Initializes `display` and makes a 4.5 core context current on it; the reason it could not,
  /// else empty.
  std::string open(void* display, void* shareContext = nullptr);

  std::string renderer_, version_, platform_;
  mutable std::vector<std::string> extensions_;  ///< sorted, read on the first hasExtension
  mutable std::map<std::string, GpuProgram, std::less<>> programs_;  ///< the program cache, by name and variant
};

/// An OpenGL buffer object (shader storage) of a fixed size.
class GpuBuffer {
 public:
  GpuBuffer() = default;
  /// `bytes` of storage (at least 16), filled from `data` when it is not null.
  explicit GpuBuffer(size_t bytes, const void* data = nullptr);
  ~GpuBuffer();
  GpuBuffer(GpuBuffer&& other) noexcept;
  GpuBuffer& operator=(GpuBuffer&& other) noexcept;
  GpuBuffer(const GpuBuffer&) = delete;
  GpuBuffer& operator=(const GpuBuffer&) = delete;

  /// A caller's buffer `id` of `bytes` bytes, used but not owned: never deleted here.
  static GpuBuffer borrowed(uint32_t id, size_t bytes);

  size_t bytes() const { return bytes_; }
  uint32_t id() const { return id_; }
  /// Binds it to shader storage binding point `index`.
  void bindStorage(uint32_t index) const;
  void write(const void* data, size_t bytes, size_t offset = 0) const;
  /// Sets every 32-bit word to `value`.
  void fill(uint32_t value) const;
  /// Reads `bytes` from `offset` after the shader writes issued before it (waits for them).
  void read(void* data, size_t bytes, size_t offset = 0) const;

 private:
  uint32_t id_ = 0;
  size_t bytes_ = 0;
  bool owned_ = true;
};

/// The OpenGL state layertrace's passes change, saved at construction and restored at
/// destruction, for a caller's context (layertrace/gpu.h): the program, the vertex array, the
/// draw and read framebuffers, the viewport, the polygon mode, the depth, cull, stencil, scissor
/// and rasterizer-discard switches, the shader storage bindings 0–15 (indexed and generic), the
/// dispatch-indirect and pixel-unpack buffers, the unpack pixel-store settings, the transform
/// feedback object, the active texture unit and the 2D textures and samplers of units 0–2.
class GpuStateGuard {
 public:
  GpuStateGuard();
  ~GpuStateGuard();
  GpuStateGuard(const GpuStateGuard&) = delete;
  GpuStateGuard& operator=(const GpuStateGuard&) = delete;

  static constexpr uint32_t kStorageBindings = 16;

 private:
  struct Binding {
    int buffer = 0;
    int64_t offset = 0, size = 0;
  };
  static constexpr std::array<uint32_t, 5> kCapabilities = {0x0B71 /*GL_DEPTH_TEST*/, 0x0B44 /*GL_CULL_FACE*/, 0x0B90 /*GL_STENCIL_TEST*/,
                                                            0x0C11 /*GL_SCISSOR_TEST*/, 0x8C89 /*GL_RASTERIZER_DISCARD*/};
  static constexpr std::array<uint32_t, 6> kUnpack = {0x0CF5 /*GL_UNPACK_ALIGNMENT*/, 0x0CF2 /*GL_UNPACK_ROW_LENGTH*/,
                                                      0x0CF3 /*GL_UNPACK_SKIP_ROWS*/,  0x0CF4 /*GL_UNPACK_SKIP_PIXELS*/,
                                                      0x806E /*GL_UNPACK_IMAGE_HEIGHT*/, 0x806D /*GL_UNPACK_SKIP_IMAGES*/};
  int program_ = 0, vertexArray_ = 0, drawFramebuffer_ = 0, readFramebuffer_ = 0;
  int viewport_[4] = {}, polygonMode_[2] = {};
  std::array<bool, kCapabilities.size()> enabled_{};
  int storage_ = 0, dispatchIndirect_ = 0, pixelUnpack_ = 0, transformFeedback_ = 0, activeTexture_ = 0;
  static constexpr uint32_t kTextureUnits = 3;  ///< the 2D textures and samplers of units 0–2 (a G-buffer's)
  std::array<int, kTextureUnits> texture2d_{}, sampler_{};
  std::array<Binding, kStorageBindings> storageIndexed_{};
  std::array<int, kUnpack.size()> unpack_{};
};

/// GPU time from begin() to end(): two GL_TIMESTAMP queries, taken when the GPU reaches them.
class GpuTimer {
 public:
  GpuTimer();
  ~GpuTimer();
  GpuTimer(const GpuTimer&) = delete;
  GpuTimer& operator=(const GpuTimer&) = delete;
  void begin() const;
  void end() const;
  /// Milliseconds of the last begin()/end(); waits for the GPU to finish them (read after the
  /// frame's last read-back, it waits no more: the work is done).
  double ms() const;

 private:
  uint32_t ids_[2] = {};
};

/// GPU time per stage over many passes: a pair of GL_TIMESTAMP queries around each, from a pool
/// kept from frame to frame, read only by collect() — after the frame's read-back, when the
/// work is done and reading waits no more.
class GpuTimeline {
 public:
  GpuTimeline() = default;
  ~GpuTimeline();
  GpuTimeline(const GpuTimeline&) = delete;
  GpuTimeline& operator=(const GpuTimeline&) = delete;
  void begin(int stage);
  void end(int stage);
  /// Milliseconds per stage (stages 0 … n − 1) since the last collect, which it starts anew.
  std::vector<double> collect(int n);

 private:
  uint32_t query();
  std::vector<uint32_t> pool_;
  size_t used_ = 0;
  std::vector<std::pair<int, size_t>> spans_;  ///< stage, its begin query (the end query follows)
};

}  // namespace lt
