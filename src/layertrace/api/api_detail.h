// What the public API's sources share and never install: the translation of layertrace's errors
// into the standard exceptions the headers promise, and the checks of the values users pass.
#pragma once

#include <stdexcept>
#include <string>

#include "layertrace/api/layertrace.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"
#include "layertrace/util/error.h"

namespace lt {

struct TriangleScene::Impl {
  Scene scene;
};

namespace api_detail {

/// Runs `f`, translating layertrace's errors into the exceptions of the public header.
template <class F>
auto guarded(F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const InputError& e) {
    throw std::invalid_argument(e.what());
  } catch (const InternalError& e) {
    throw std::runtime_error(std::string("layertrace internal error: ") + e.what());
  }
}

[[noreturn]] inline void invalid(const std::string& message) { throw std::invalid_argument(message); }

/// The registry parameter named `name` (its flag without the dashes).
const TracerParam& paramNamed(const std::string& name);
/// The library's options for `params`: the preset, then every value set, as the CLI applies them.
TracerOptions tracerOptions(const TracerParams& params);
/// The camera of `view`, checked (std::invalid_argument naming the bad field).
Camera cameraOf(const View& view);
/// The z-thickness per unit depth of `thicknessPx` pixel footprints, checked.
float thicknessPerDepth(const Camera& camera, float thicknessPx);

}  // namespace api_detail
}  // namespace lt
