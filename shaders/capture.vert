#version 450
// The capture's geometry pass: camera-space vertices to clip space. Drawn indexed, so
// gl_VertexID is the scene's vertex index and gl_PrimitiveID in the fragment stage its triangle.
layout(std430, binding = 7) readonly buffer CamPos { vec4 camPos[]; };
uniform mat4 uProjection;

void main() {
  gl_Position = uProjection * vec4(camPos[gl_VertexID].xyz, 1.0);
}
