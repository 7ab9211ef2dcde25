#version 450
// A caller's G-buffer (layertrace/gpu.h GpuGBuffer) as one layer of the k-layer arrays (k = 1):
// per pixel the depth texture's window depth back to the positive camera-space depth of an
// OpenGL perspective projection with the view's near and far planes and the default depth
// range, the normal (encoded octahedrally, as the capture encodes it), the albedo as sRGB codes
// and the specular weight, and the z-thickness of the view's rule. Rows are flipped: OpenGL's
// row 0 is the bottom, the layers' the top. A depth of 1 (nothing drawn) leaves the pixel empty.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)

#include "capture_common.glsl"

uniform sampler2D uDepth, uNormals, uAlbedo;
uniform float uThickness, uThicknessPerDepth;
uniform bool uNormalsUnsigned, uHaveAlbedo;
layout(std430, binding = 0) writeonly buffer Slots { uvec4 slots[]; };
layout(std430, binding = 1) writeonly buffer Counts { uint counts[]; };

uint srgbCode(float linear) {
  const float c = clamp(linear, 0.0, 1.0);
  const float s = c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
  return uint(floor(s * 255.0 + 0.5));
}

void main() {
  const uint p = gl_GlobalInvocationID.x + uint(uFirst);
  if (p >= uint(uWidth * uHeight)) return;
  const int x = int(p % uint(uWidth)), y = int(p / uint(uWidth));
  const ivec2 texel = ivec2(x, uHeight - 1 - y);
  const float window = texelFetch(uDepth, texel, 0).r;
  if (!(window < 1.0)) {
    counts[p] = 0u;
    slots[p] = uvec4(0u);
    return;
  }
  const float ndc = 2.0 * window - 1.0;
  const float depth = 2.0 * uNear * uFar / ((uFar + uNear) - ndc * (uFar - uNear));
  vec3 n = texelFetch(uNormals, texel, 0).xyz;
  if (uNormalsUnsigned) n = n * 2.0 - 1.0;
  n = dot(n, n) > 0.0 ? normalize(n) : vec3(0.0, 0.0, 1.0);
  const vec4 albedo = uHaveAlbedo ? texelFetch(uAlbedo, texel, 0) : vec4(0.5, 0.5, 0.5, 0.0);
  const uint albedoSpec = srgbCode(albedo.r) | (srgbCode(albedo.g) << 8) | (srgbCode(albedo.b) << 16) |
                          (uint(floor(clamp(albedo.a, 0.0, 1.0) * 255.0 + 0.5)) << 24);
  counts[p] = 1u;
  slots[p] = uvec4(floatBitsToUint(depth), encodeOctahedral(n), albedoSpec, floatBitsToUint(uThickness + uThicknessPerDepth * depth));
}
