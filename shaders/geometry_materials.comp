#version 450
// A caller's geometry (layertrace/gpu.h): its draw calls' vertices arrive by transform feedback,
// three a triangle in draw order, each with the material index its vertex shader wrote. A
// triangle takes its first vertex's material, held to the materials the renderer knows, so that
// a wrong index shades with the last material rather than reading past the table.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uTriangleCount, uMaterialCount;
layout(std430, binding = 0) readonly buffer VertexMaterial { uint vertexMaterial[]; };
layout(std430, binding = 1) writeonly buffer TriMaterial { uint triMaterial[]; };

void main() {
  const uint t = gl_GlobalInvocationID.x + uint(uFirst);
  if (t >= uint(uTriangleCount)) return;
  triMaterial[t] = min(vertexMaterial[3u * t], uint(uMaterialCount - 1));
}
