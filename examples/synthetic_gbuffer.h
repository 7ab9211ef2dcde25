// A depth buffer made without layertrace, as an engine would hand it over: a tilted floor plane
// and a box standing on it, seen by a pinhole camera, ray-cast analytically per pixel. Also the
// triangles it was made of, for classify_against_embree.cpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>
#include <layertrace/layertrace.h>

namespace example {

struct GBuffer {
  lt::View view;
  std::vector<float> depth;           // per pixel, +inf where nothing is seen
  std::vector<glm::vec3> normals;     // camera space
  std::vector<glm::vec3> positions;   // world-space triangles of the scene
  std::vector<glm::uvec3> triangles;
};

inline void addQuad(GBuffer& g, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
  const uint32_t i = uint32_t(g.positions.size());
  g.positions.insert(g.positions.end(), {a, b, c, d});
  g.triangles.push_back({i, i + 1, i + 2});
  g.triangles.push_back({i, i + 2, i + 3});
}

/// Closest intersection of a world ray with a triangle (Möller–Trumbore), or +inf.
inline float hitTriangle(glm::vec3 o, glm::vec3 d, glm::vec3 a, glm::vec3 b, glm::vec3 c) {
  const glm::vec3 e1 = b - a, e2 = c - a, p = glm::cross(d, e2);
  const float det = glm::dot(e1, p);
  if (std::abs(det) < 1e-12f) return std::numeric_limits<float>::infinity();
  const glm::vec3 s = o - a;
  const float u = glm::dot(s, p) / det;
  const glm::vec3 q = glm::cross(s, e1);
  const float v = glm::dot(d, q) / det, t = glm::dot(e2, q) / det;
  return u >= 0 && v >= 0 && u + v <= 1 && t > 0 ? t : std::numeric_limits<float>::infinity();
}

inline GBuffer makeGBuffer(int width, int height) {
  GBuffer g;
  g.view.eye = {0.0f, 2.0f, 6.0f};
  g.view.target = {0.0f, 0.0f, 0.0f};
  g.view.fovY = 50.0f;
  g.view.width = width, g.view.height = height;
  g.view.near = 0.05f, g.view.far = 100.0f;
  // A floor tilted by a few degrees, and a box on it.
  addQuad(g, {-8, -0.3f, -8}, {-8, 0.3f, 8}, {8, 0.3f, 8}, {8, -0.3f, -8});
  const glm::vec3 lo{-1.0f, 0.0f, -1.0f}, hi{1.0f, 1.5f, 0.5f};
  addQuad(g, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z});  // front
  addQuad(g, {hi.x, lo.y, lo.z}, {lo.x, lo.y, lo.z}, {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z});  // back
  addQuad(g, {lo.x, lo.y, lo.z}, {lo.x, lo.y, hi.z}, {lo.x, hi.y, hi.z}, {lo.x, hi.y, lo.z});  // left
  addQuad(g, {hi.x, lo.y, hi.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {hi.x, hi.y, hi.z});  // right
  addQuad(g, {lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z});  // top
  // Ray-cast every pixel centre: depth = distance along the view direction (camera -z).
  g.depth.assign(size_t(width) * size_t(height), std::numeric_limits<float>::infinity());
  g.normals.assign(g.depth.size(), glm::vec3(0, 0, 1));
  const glm::vec3 eyeCam = lt::worldToCamera(g.view, g.view.eye);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const glm::vec3 dirCam = lt::pixelDirection(g.view, float(x) + 0.5f, float(y) + 0.5f);
      const glm::vec3 dirWorld = glm::normalize(lt::cameraToWorld(g.view, dirCam) - lt::cameraToWorld(g.view, eyeCam));
      float best = std::numeric_limits<float>::infinity();
      glm::vec3 n(0.0f);
      for (const glm::uvec3& t : g.triangles) {
        const glm::vec3 a = g.positions[t.x], b = g.positions[t.y], c = g.positions[t.z];
        const float d = hitTriangle(g.view.eye, dirWorld, a, b, c);
        if (d < best) best = d, n = glm::normalize(glm::cross(b - a, c - a));
      }
      if (!std::isfinite(best)) continue;
      const size_t p = size_t(y) * size_t(width) + size_t(x);
      g.depth[p] = -(dirCam * best).z;  // camera-space depth of the hit
      const glm::vec3 nCam = lt::worldToCamera(g.view, g.view.eye + n) - eyeCam;
      g.normals[p] = glm::dot(nCam, dirCam) > 0 ? -nCam : nCam;  // facing the camera
    }
  return g;
}

/// One mirror-reflection ray per covered pixel, in camera space, from the stored surface.
inline std::vector<lt::Ray> reflectionRays(const GBuffer& g) {
  std::vector<lt::Ray> rays;
  for (int y = 0; y < g.view.height; ++y)
    for (int x = 0; x < g.view.width; ++x) {
      const size_t p = size_t(y) * size_t(g.view.width) + size_t(x);
      if (!std::isfinite(g.depth[p])) continue;
      const glm::vec3 dir = lt::pixelDirection(g.view, float(x) + 0.5f, float(y) + 0.5f);
      lt::Ray r;
      r.origin = dir * (g.depth[p] / -dir.z);
      r.dir = glm::normalize(glm::reflect(dir, g.normals[p]));
      r.maxDistance = 50.0f;
      rays.push_back(r);
    }
  return rays;
}

}  // namespace example
