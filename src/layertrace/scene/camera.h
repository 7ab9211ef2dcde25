// The pinhole camera and the one depth convention of layertrace.
//
// DEPTH CONVENTION (used everywhere): "depth" is the positive linear eye-space distance along the
// viewing direction, depth = -z_view. Camera space is right-handed, looking down -z, +y up.
// Screen space is in pixels: x to the right, y DOWN, pixel (i, j) covers [i, i+1) x [j, j+1)
// and is sampled at its centre (i + 0.5, j + 0.5).
#pragma once

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "layertrace/scene/scene.h"

namespace lt {

class Camera {
 public:
  Camera() = default;
  Camera(const CameraDesc& desc, int width, int height);

  int width() const { return width_; }
  int height() const { return height_; }
  float near() const { return near_; }
  float far() const { return far_; }
  const CameraDesc& desc() const { return desc_; }

  const glm::mat4& view() const { return view_; }        ///< world → camera
  const glm::mat4& viewInverse() const { return viewInv_; }
  /// Camera space → homogeneous pixel space: (x', y', z', w) with w = depth, x'/w, y'/w in pixels.
  const glm::mat4& pixelProjection() const { return pixelProj_; }
  /// Camera space → OpenGL clip space (z in [-w, w] between near and far).
  const glm::mat4& clipProjection() const { return clipProj_; }

  glm::vec3 toCamera(glm::vec3 world) const { return glm::vec3(view_ * glm::vec4(world, 1.0f)); }
  glm::vec3 dirToCamera(glm::vec3 world) const { return glm::vec3(view_ * glm::vec4(world, 0.0f)); }
  glm::vec3 toWorld(glm::vec3 cam) const { return glm::vec3(viewInv_ * glm::vec4(cam, 1.0f)); }
  glm::vec3 dirToWorld(glm::vec3 cam) const { return glm::vec3(viewInv_ * glm::vec4(cam, 0.0f)); }

  /// Camera-space point → pixel coordinates (continuous).
  glm::vec2 project(glm::vec3 cam) const;

  /// The pixel of a camera-space point: false when it lies in front of the near plane or off
  /// the screen.
  bool pixelOf(glm::vec3 cam, int& x, int& y) const {
    if (-cam.z < near_) return false;
    const glm::vec2 s = project(cam);
    if (!(s.x >= 0.0f && s.y >= 0.0f && s.x < float(width_) && s.y < float(height_))) return false;
    x = int(s.x), y = int(s.y);
    return true;
  }

  /// Camera-space direction through the screen point `pixel` whose depth component is 1
  /// (so a point at parameter t along it has depth t). Orthographic: (0, 0, -1) everywhere.
  /// Inline: the rasterizer evaluates it once per fragment.
  glm::vec3 rayThrough(glm::vec2 pixel) const {
    if (ortho_) return {0.0f, 0.0f, -1.0f};
    return {(pixel.x - float(width_) * 0.5f) * pixelScale_, -(pixel.y - float(height_) * 0.5f) * pixelScale_, -1.0f};
  }

  /// Camera-space origin of the ray through `pixel`: the eye (0, 0, 0) for a pinhole camera, the
  /// pixel's point on the z = 0 plane for an orthographic one.
  glm::vec3 rayOrigin(glm::vec2 pixel) const {
    if (!ortho_) return glm::vec3(0.0f);
    return {(pixel.x - float(width_) * 0.5f) * pixelScale_, -(pixel.y - float(height_) * 0.5f) * pixelScale_, 0.0f};
  }

  /// An orthographic camera (CameraDesc::orthoHeight > 0): x_px = W/2 + focal·x, y_px = H/2 −
  /// focal·y, with focal in pixels per scene unit; depth = -z as always.
  bool orthographic() const { return ortho_; }

  /// Focal length in pixels: x_px = W/2 + focal·x/depth, y_px = H/2 − focal·y/depth
  /// (orthographic: pixels per scene unit, no division by depth).
  float focal() const { return focal_; }

  /// Pixel footprint (world size of one pixel) at the given depth.
  float pixelFootprint(float depth) const { return ortho_ ? pixelScale_ : depth * pixelScale_; }

 private:
  CameraDesc desc_;
  int width_ = 0, height_ = 0;
  float near_ = 0.1f, far_ = 100.0f;
  float focal_ = 1.0f;       ///< focal length in pixels
  float pixelScale_ = 1.0f;  ///< 1 / focal_
  bool ortho_ = false;
  glm::mat4 view_{1.0f}, viewInv_{1.0f}, pixelProj_{1.0f}, clipProj_{1.0f};
};

// A view looking straight along its up vector gets the world axis least aligned with the view
// direction as up (documented fallback instead of an error).

/// Camera framing the whole scene from the front-top diagonal; used when a scene has no camera.
CameraDesc autoCamera(const Scene& scene);

/// Fills near/far where they are 0: near = 1e-4 · scene diagonal (at least 1e-4), far = the
/// distance to the farthest bounding-box corner, plus 1 %.
CameraDesc withClipPlanes(CameraDesc desc, const Scene& scene);

}  // namespace lt
