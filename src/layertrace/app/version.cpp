#include "layertrace/app/version.h"
#include "layertrace/pipeline/gpu_tracers.h"

#include <sstream>

#include <assimp/version.h>
#include <embree3/rtcore_config.h>

#include "layertrace/commit.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/render/effects.h"
#include "layertrace/util/simd_targets.h"

namespace lt {

std::string versionText(bool viewer) {
  std::ostringstream s;
  s << "layertrace " << LAYERTRACE_VERSION << " (commit " << LAYERTRACE_COMMIT << ", " << LAYERTRACE_BUILD_TYPE << " build)\n";
  s << "  per-ray counters: " << (kCountersCompiled ? "on" : "off (compiled out)") << "\n";
  s << "  vector lanes (Highway): " << activeSimdTarget().name << " (this CPU runs:";
  for (const SimdTarget& t : simdTargets()) s << " " << t.name;
  s << ")\n";
#if defined(__SANITIZE_ADDRESS__)
  s << "  sanitizers: address, undefined\n";
#elif defined(__SANITIZE_THREAD__)
  s << "  sanitizers: thread\n";
#endif
  s << "  viewer: " << (viewer ? "on" : "off (needs GLFW, OpenGL and Dear ImGui)") << "\n";
  s << "  GPU back end: " << (gpuBuilt() ? "built (OpenGL 4.5 compute through headless EGL; --device gpu)" : "not built (needs libepoxy-dev, libegl-dev, glslang-tools)") << "\n";
  s << "  Embree " << RTC_VERSION_STRING << ", assimp " << aiGetVersionMajor() << "." << aiGetVersionMinor() << "." << aiGetVersionPatch() << "\n";
  return s.str();
}

namespace {
const char* kindName(TracerKind k) {
  switch (k) {
    case TracerKind::Screen: return "image space (the camera's k layers)";
    case TracerKind::ViewIndependent: return "view-independent (layered depth cube of the scene box)";
    case TracerKind::Geometric: return "geometric (the scene's triangles)";
    case TracerKind::Hybrid: return "hybrid (image space, then geometry)";
  }
  return "";
}
}  // namespace

std::string tracersText() {
  std::ostringstream s;
  const TracerOptions defaults;
  s << "Tracers (render/view --tracer NAME, compare --tracers A,B,...):\n";
  for (const TracerEntry& e : tracerRegistry()) {
    s << "\n  " << e.info.name << ": " << e.info.summary << "\n";
    s << "    kind: " << kindName(e.info.kind) << "\n";
    if (*e.info.paper) s << "    paper: " << e.info.paper << "\n";
    for (const char* group : e.groups)
      for (const TracerParam& p : tracerParams())
        if (std::string_view(p.group) == group && e.reads(p)) {
          s << "    " << p.flag << " " << paramValue(p, defaults) << "  " << p.help;
          if (*p.alias) s << " (also " << p.alias << ")";
          s << "\n";
        }
  }
  const EffectConfig e;
  s << "\nEffects (--effect NAME; every tracer traces every effect):\n"
    << "  shade       direct light at the primary hit, no secondary rays\n"
    << "  reflection  mirror reflections from every covered pixel; --bounces " << e.bounces << ", --max-distance "
    << e.maxDistance << " (0 = the scene diagonal)\n"
    << "  refraction  one refraction through the first surface; --max-distance " << e.maxDistance << "\n"
    << "  ao          ambient occlusion; --ao-samples " << e.aoSamples << ", --ao-radius " << e.aoRadius
    << " (0 = 5 % of the scene diagonal)\n"
    << "  shadow      shadow rays to every light (--light x,y,z[,intensity])\n"
    << "  warp        view synthesis: the layers seen from --warp-eye x,y,z [--warp-target x,y,z]\n";
  return s.str();
}

}  // namespace lt
