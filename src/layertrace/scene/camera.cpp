#include "layertrace/scene/camera.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/matrix_inverse.hpp>

#include "layertrace/util/error.h"

namespace lt {

Camera::Camera(const CameraDesc& desc, int width, int height)
    : desc_(desc), width_(width), height_(height), near_(desc.near), far_(desc.far) {
  LT_CHECK(width > 0 && height > 0, width, "x", height);
  LT_CHECK(near_ > 0.0f && far_ > near_, near_, " ", far_);
  const glm::vec3 fwd = desc.target - desc.eye;
  if (!(glm::length(fwd) > 0.0f)) inputError("camera ", desc.name, ": eye and target coincide");
  if (!(glm::length(desc.up) > 0.0f)) inputError("camera ", desc.name, ": up vector is zero");
  if (!(glm::length(glm::cross(glm::normalize(fwd), glm::normalize(desc.up))) > 1e-4f)) {
    // Looking straight along `up` (e.g. straight down at a Y-up scene): use the world axis least
    // aligned with the view as up instead of failing.
    const glm::vec3 f = glm::abs(glm::normalize(fwd));
    desc_.up = f.x <= f.y && f.x <= f.z ? glm::vec3(1, 0, 0) : f.y <= f.z ? glm::vec3(0, 1, 0) : glm::vec3(0, 0, 1);
  }
  ortho_ = desc.orthoHeight > 0.0f;
  if (!ortho_ && !(desc.fovY > 0.0f && desc.fovY < 180.0f))
    inputError("camera ", desc.name, ": fov ", desc.fovY, " is not in (0, 180) degrees");
  view_ = glm::lookAt(desc_.eye, desc_.target, desc_.up);
  viewInv_ = glm::inverse(view_);
  if (ortho_) {
    LT_CHECK(std::isfinite(desc.orthoHeight), desc.orthoHeight);
    focal_ = float(height) / desc.orthoHeight;
    pixelScale_ = 1.0f / focal_;
    // x_px = W/2 + f x, y_px = H/2 - f y, w = 1.
    pixelProj_ = glm::mat4(0.0f);
    pixelProj_[0][0] = focal_;
    pixelProj_[3][0] = float(width) * 0.5f;
    pixelProj_[1][1] = -focal_;
    pixelProj_[3][1] = float(height) * 0.5f;
    pixelProj_[2][2] = 1.0f;
    pixelProj_[3][3] = 1.0f;
    const float hw = 0.5f * float(width) * pixelScale_, hh = 0.5f * desc.orthoHeight;
    clipProj_ = glm::ortho(-hw, hw, -hh, hh, near_, far_);
    return;
  }
  const float tanHalf = std::tan(glm::radians(desc.fovY) * 0.5f);
  focal_ = float(height) * 0.5f / tanHalf;
  pixelScale_ = 1.0f / focal_;
  // Pixel projection: x_px = W/2 + f * x / depth, y_px = H/2 - f * y / depth, depth = -z.
  pixelProj_ = glm::mat4(0.0f);
  pixelProj_[0][0] = focal_;
  pixelProj_[2][0] = -float(width) * 0.5f;
  pixelProj_[1][1] = -focal_;
  pixelProj_[2][1] = -float(height) * 0.5f;
  pixelProj_[2][2] = 1.0f;   // z' = z (unused)
  pixelProj_[2][3] = -1.0f;  // w = -z = depth
  clipProj_ = glm::perspective(glm::radians(desc.fovY), float(width) / float(height), near_, far_);
}

glm::vec2 Camera::project(glm::vec3 cam) const {
  if (ortho_) return {float(width_) * 0.5f + focal_ * cam.x, float(height_) * 0.5f - focal_ * cam.y};
  const float depth = -cam.z;
  return {float(width_) * 0.5f + focal_ * cam.x / depth, float(height_) * 0.5f - focal_ * cam.y / depth};
}

CameraDesc autoCamera(const Scene& scene) {
  const Bounds b = scene.bounds();
  const glm::vec3 c = b.center();
  const float r = 0.5f * b.diagonal();
  CameraDesc d;
  d.name = "auto";
  d.fovY = 45.0f;
  const float dist = r / std::sin(glm::radians(d.fovY) * 0.5f);
  d.eye = c + glm::normalize(glm::vec3(0.35f, 0.45f, 1.0f)) * dist;
  d.target = c;
  d.up = {0.0f, 1.0f, 0.0f};
  return d;
}

CameraDesc withClipPlanes(CameraDesc d, const Scene& scene) {
  const Bounds b = scene.bounds();
  // Relative to the scene only (an absolute floor of 1e-4 clipped away a whole scene 1e-6 across).
  if (d.near <= 0.0f) d.near = std::max(1e-4f * b.diagonal(), 1e-30f);
  if (d.far <= 0.0f) {
    d.far = std::max(b.farthestFrom(d.eye) * 1.01f, d.near * 10.0f);
  }
  if (!(d.far > d.near)) inputError("camera ", d.name, ": far ", d.far, " is not beyond near ", d.near);
  if (!std::isfinite(d.far)) inputError("camera ", d.name, ": the eye ", d.eye.x, ",", d.eye.y, ",", d.eye.z, " is too far from the scene (the far plane overflows)");
  return d;
}

}  // namespace lt
