#version 450
// Between two rounds of the origin rule (effect_resolve.comp): the rays still pending decide
// the next round's work groups, written as indirect dispatch arguments, so that the host issues
// every round without waiting to learn whether it is needed. One invocation.
layout(local_size_x = 1) in;
layout(std430, binding = 6) readonly buffer Pending { uint pendingRays; };
// [0..2]: the plain march and the resolve pass; [3..5]: the persistent march (§5.3).
layout(std430, binding = 7) writeonly buffer Groups { uint groups[8]; };
uniform uint uGroups;            // work groups of 64 over every ray slot
uniform uint uPersistentGroups;  // the persistent march's groups

void main() {
  const bool again = pendingRays > 0u;
  groups[0] = again ? uGroups : 0u;
  groups[1] = 1u;
  groups[2] = 1u;
  groups[3] = again ? uPersistentGroups : 0u;
  groups[4] = 1u;
  groups[5] = 1u;
}
