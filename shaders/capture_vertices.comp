#version 450
// The capture's first pass: every vertex to camera space (point and normal; the view is rigid,
// so its upper 3×3 turns normals), as raster_setup.cpp prepareRaster does.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
layout(std430, binding = 0) readonly buffer Positions { float positions[]; };
layout(std430, binding = 1) readonly buffer Normals { float normals[]; };
layout(std430, binding = 2) writeonly buffer CamPos { vec4 camPos[]; };
layout(std430, binding = 3) writeonly buffer CamNormals { vec4 camNormals[]; };
uniform int uVertexCount;
uniform mat4 uView;

void main() {
  const uint v = gl_GlobalInvocationID.x + uint(uFirst);
  if (v >= uint(uVertexCount)) return;
  const vec3 p = vec3(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
  const vec3 n = vec3(normals[3u * v], normals[3u * v + 1u], normals[3u * v + 2u]);
  // glm's order of operations (mat4 · vec4: (m0 x + m1 y) + (m2 z + m3); mat3 · vec3: left to
  // right), so camera-space vertices are the CPU's bits.
  precise vec4 c = (uView[0] * p.x + uView[1] * p.y) + (uView[2] * p.z + uView[3]);
  precise vec3 cn = (uView[0].xyz * n.x + uView[1].xyz * n.y) + uView[2].xyz * n.z;
  camPos[v] = vec4(c.xyz, 1.0);
  camNormals[v] = vec4(cn, 0.0);
}
