#version 450
// The irregular grid's build on the GPU (gpu/gpu_grid_build.h): the voxel map's leaves point at
// the walk unit of the cell that holds them, one invocation per leaf.
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Owners { uint owners[]; };  // per leaf: its live cell
layout(std430, binding = 1) readonly buffer Units { uint units[]; };    // per cell: its first walk unit
layout(std430, binding = 2) writeonly buffer Leaves { uint leaves[]; };

uniform int uFirst, uLeaves;

void main() {
  const uint l = gl_GlobalInvocationID.x + uint(uFirst);
  if (l < uint(uLeaves)) leaves[l] = units[owners[l]];
}
