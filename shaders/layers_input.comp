#version 450
// Layers a caller made (layertrace/gpu.h GpuLayers) into the frame's k-layer arrays, in place of
// a capture: the slots as they are, the counts held to k (a larger count would read the next
// pixel's slots), and per slot the material index held to the materials the renderer knows, in
// the place of the slot's triangle (the renderer's triangle t is a record of material t). The
// depth complexity is the count, and the fragments counted are the slots kept.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uPixels, uK, uMaterialCount;
uniform bool uHaveMaterials;
layout(std430, binding = 0) readonly buffer InSlots { uvec4 inSlots[]; };
layout(std430, binding = 1) readonly buffer InCounts { uint inCounts[]; };
layout(std430, binding = 2) readonly buffer InMaterials { uint inMaterials[]; };
layout(std430, binding = 3) writeonly buffer Slots { uvec4 slots[]; };
layout(std430, binding = 4) writeonly buffer Counts { uint counts[]; };
layout(std430, binding = 5) writeonly buffer SlotTriangle { uint slotTriangle[]; };
layout(std430, binding = 6) writeonly buffer Complexity { uint complexity[]; };
layout(std430, binding = 7) buffer Counter { uint kept; };

void main() {
  const uint p = gl_GlobalInvocationID.x + uint(uFirst);
  if (p >= uint(uPixels)) return;
  const uint n = min(inCounts[p], uint(uK));
  counts[p] = n;
  complexity[p] = n;
  atomicAdd(kept, n);
  for (uint j = 0u; j < uint(uK); ++j) {
    const uint s = p * uint(uK) + j;
    if (j < n) {
      slots[s] = inSlots[s];
      slotTriangle[s] = uHaveMaterials ? min(inMaterials[s], uint(uMaterialCount - 1)) : 0u;
    } else {
      slots[s] = uvec4(0u);
      slotTriangle[s] = 0xFFFFFFFFu;
    }
  }
}
