// The attributes of a kept fragment of pixel (px, py) on `triangle` at `depth`: its octahedral
// camera-space normal and its albedo and specular, evaluated where the pixel-centre ray meets the
// triangle (the alpha test already passed). Needs capture_common.glsl and capture_surface.glsl
// before it, and the camera-space vertex normals declared as `camNormals`.
uvec2 fragmentAttributes(TriangleSetup ts, uint triangle, int px, int py, float depth) {
  vec3 origin, dir;
  pixelRay(px, py, origin, dir);
  const uint normal = fragmentNormal(ts, camNormals[ts.info.x].xyz, camNormals[ts.info.y].xyz, camNormals[ts.info.z].xyz, origin, dir, depth);
  uint albedoSpec;
  fragmentSurface(ts, triangle, origin, dir, depth, true, albedoSpec);
  return uvec2(normal, albedoSpec);
}
