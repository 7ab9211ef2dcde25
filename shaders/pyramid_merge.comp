#version 450
// One level L ≥ 1 of the interval pyramid of Hofmann et al. 2017, §4.3 (Figure 3 right): each
// cell merges the intervals of its 2×2 children front to back, a parent interval taking every
// child interval that starts within τ of its start or inside it — the CPU's mergeChildren
// (src/layertrace/hssr/interval_pyramid_build.cpp), whose result depends on the order of fronts
// only. The children's lists are each sorted by front, so a four-way merge streams them in
// front order with no storage. Two passes: uPass 0 counts each cell's intervals (an exclusive
// scan then turns the counts into offsets), uPass 1 writes them, and the fixed-slot κ cell the
// march reads (CoarseCell: at most four intervals, the pairs separated by the smallest gaps
// merged first).
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)

layout(std430, binding = 0) readonly buffer Level0 { vec2 level0[]; };          // L = 1: k per pixel
layout(std430, binding = 1) readonly buffer Counts { uint counts[]; };          // L = 1: per pixel
layout(std430, binding = 2) readonly buffer ChildOffset { uint childOffset[]; };  // L > 1: CSR of L − 1
layout(std430, binding = 3) readonly buffer ChildIntervals { vec2 childIntervals[]; };
layout(std430, binding = 4) buffer Offset { uint offsets[]; };    // pass 0: counts; pass 1: offsets (scanned)
layout(std430, binding = 5) buffer Intervals { vec2 intervals[]; };
layout(std430, binding = 6) writeonly buffer Cells { vec4 cells[]; };

uniform int uPass, uLevel, uK;
uniform int uWidth, uHeight, uChildWidth, uChildHeight;
uniform float uTauPerDepth;
uniform uint uCellBase;  // this level's first cell in Cells
uniform uint uCapacity;  // intervals the Intervals buffer holds (a resident build may need more: written up to it)

#define kInf uintBitsToFloat(0x7f800000u)

// The four children: where their lists start and how long they are.
uint childBase[4], childCount[4], childAt[4];
int children;

bool fromLevel0() { return uLevel == 1; }
vec2 childInterval(int c, uint i) { return fromLevel0() ? level0[childBase[c] + i] : childIntervals[childBase[c] + i]; }

// The next child interval in front order (ties: the lower child), or false when none is left.
bool nextInterval(out vec2 v) {
  int best = -1;
  float bestFront = 0.0;
  for (int c = 0; c < children; ++c) {
    if (childAt[c] >= childCount[c]) continue;
    const float f = childInterval(c, childAt[c]).x;
    if (best < 0 || f < bestFront) {
      best = c;
      bestFront = f;
    }
  }
  if (best < 0) return false;
  v = childInterval(best, childAt[best]);
  ++childAt[best];
  return true;
}

void main() {
  const uint cell = gl_GlobalInvocationID.x + uint(uFirst);
  if (cell >= uint(uWidth * uHeight)) return;
  const int x = int(cell % uint(uWidth)), y = int(cell / uint(uWidth));
  children = 0;
  for (int cy = 2 * y; cy < min(2 * y + 2, uChildHeight); ++cy)
    for (int cx = 2 * x; cx < min(2 * x + 2, uChildWidth); ++cx) {
      const uint child = uint(cy) * uint(uChildWidth) + uint(cx);
      childBase[children] = fromLevel0() ? child * uint(uK) : childOffset[child];
      childCount[children] = fromLevel0() ? counts[child] : childOffset[child + 1u] - childOffset[child];
      childAt[children] = 0u;
      ++children;
    }
  const uint first = uPass == 1 ? offsets[cell] : 0u;
  uint n = 0u;
  vec2 cur;
  if (nextInterval(cur)) {
    vec2 v;
    for (;;) {
      precise float limit = cur.x + uTauPerDepth * cur.x;
      const bool more = nextInterval(v);
      if (more && (v.x <= limit || v.x <= cur.y)) {
        cur.y = max(cur.y, v.y);
        continue;
      }
      if (uPass == 1 && first + n < uCapacity) intervals[first + n] = cur;
      ++n;
      if (!more) break;
      cur = v;
    }
  }
  if (uPass == 0) {
    offsets[cell] = n;
    return;
  }
  // A level that overflowed its buffer is built again with a larger one: its cells can wait.
  if (first + n > uCapacity) return;
  // The κ cell. The intervals are disjoint and sorted, so their backs grow too: merging the
  // pair across the smallest gap, again and again until four remain (ties: the first such pair),
  // keeps exactly the three largest gaps (ties: the later gap) as separators.
  uint keep[3] = uint[3](0u, 0u, 0u);  // the gaps kept: gap g lies between intervals g and g + 1
  int kept = 0;
  if (n > 4u) {
    for (int r = 0; r < 3; ++r) {
      uint best = 0u;
      float bestGap = 0.0;
      bool found = false;
      for (uint g = 0u; g + 1u < n; ++g) {
        if ((r > 0 && g == keep[0]) || (r > 1 && g == keep[1])) continue;
        precise float gap = intervals[first + g + 1u].x - intervals[first + g].y;
        if (!found || gap >= bestGap) {
          found = true;
          best = g;
          bestGap = gap;
        }
      }
      keep[r] = best;
    }
    kept = 3;
  }
  vec4 kFront = vec4(-kInf), kBack = vec4(kInf);
  int slot = 0;
  uint start = 0u;
  for (uint i = 0u; i < n; ++i) {
    const bool ends = n <= 4u || i + 1u == n || (kept == 3 && (i == keep[0] || i == keep[1] || i == keep[2]));
    if (!ends) continue;
    precise float kf = 1.0 / intervals[first + start].x;
    precise float kb = 1.0 / intervals[first + i].y;
    kFront[slot] = kf;
    kBack[slot] = kb;
    ++slot;
    start = i + 1u;
  }
  cells[2u * (uCellBase + cell)] = kFront;
  cells[2u * (uCellBase + cell) + 1u] = kBack;
}
