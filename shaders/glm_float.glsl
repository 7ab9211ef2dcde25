// The float functions of the CPU code (glm, the standard library, raster/fragment.cpp) in their
// order of operations, so that a shader computes the CPU's bits on an IEEE device. `precise`
// keeps the compiler from contracting or reassociating (the CPU build uses -ffp-contract=off).

// std::min and std::max: the first argument unless the second is strictly smaller (larger), so
// that the choice between equal values (+0 and −0) is the CPU's.
float minStd(float a, float b) { return b < a ? b : a; }
float maxStd(float a, float b) { return a < b ? b : a; }

// −x with the sign bit flipped, so that −(+0) is −0 as on the CPU (a driver may negate as 0 − x).
float negStd(float x) { return uintBitsToFloat(floatBitsToUint(x) ^ 0x80000000u); }

// 0 + x as IEEE arithmetic gives it (−0 becomes +0): the first term of a CPU sum that starts at
// zero, which a compiler may fold to x.
float zeroPlus(float x) { return floatBitsToUint(x) == 0x80000000u ? 0.0 : x; }
vec3 zeroPlus(vec3 v) { return vec3(zeroPlus(v.x), zeroPlus(v.y), zeroPlus(v.z)); }

// glm::dot: the products summed from x to z.
float dotStd(vec3 a, vec3 b) {
  precise float d = a.x * b.x + a.y * b.y + a.z * b.z;
  return d;
}

// glm::normalize: v · (1 / sqrt(v·v)), the sum from x to z.
vec3 normalizeStd(vec3 v) {
  precise float d = v.x * v.x + v.y * v.y + v.z * v.z;
  precise vec3 n = v * (1.0 / sqrt(d));
  return n;
}

// glm::cross.
vec3 crossStd(vec3 x, vec3 y) {
  precise vec3 c = vec3(x.y * y.z - y.y * x.z, x.z * y.x - y.z * x.x, x.x * y.y - y.x * x.y);
  return c;
}

// glm's mat4 · vec4 (Camera::toCamera, toWorld, dirTo*): (m0 x + m1 y) + (m2 z + m3 w).
vec3 transformPoint(mat4 m, vec3 p) {
  precise vec4 r = (m[0] * p.x + m[1] * p.y) + (m[2] * p.z + m[3]);
  return r.xyz;
}
vec3 transformDirection(mat4 m, vec3 d) {
  precise vec4 r = (m[0] * d.x + m[1] * d.y) + (m[2] * d.z + m[3] * 0.0);
  return r.xyz;
}

// raster/fragment.cpp decodeOctahedral.
float fromSnorm16(uint bits) {
  return max(float(bitfieldExtract(int(bits), 0, 16)) / 32767.0, -1.0);
}
vec3 decodeOctahedral(uint bits) {
  const vec2 p = vec2(fromSnorm16(bits & 0xFFFFu), fromSnorm16(bits >> 16));
  precise vec3 n = vec3(p.x, p.y, 1.0 - abs(p.x) - abs(p.y));
  if (n.z < 0.0) {
    const vec2 s = vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    precise vec2 q = (1.0 - abs(vec2(n.y, n.x))) * s;
    n.x = q.x;
    n.y = q.y;
  }
  precise float len = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  return vec3(n.x / len, n.y / len, n.z / len);
}
