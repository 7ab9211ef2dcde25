#include "layertrace/ldc/ldc_method.h"

namespace lt {

std::span<const Param<LdcConfig>> ldcParams() {
  static const Param<LdcConfig> params[] = {
      {"--ldc-resolution", "", "texels along the scene box's longest axis (paper: 512, 1024)", &LdcConfig::resolution},
      {"--ldc-block", "", "coarse block edge in texels", &LdcConfig::block},
      {"--ldc-block-intervals", "", "depth intervals per block (1 = the paper's min/max)", &LdcConfig::blockIntervals, "1"},
      {"--ldc-epsilon", "", "hit tolerance in texels (a sample's patch is widened by this much)", &LdcConfig::epsilon},
      {"--ldc-hit-distance", "", "hit where the ray passes a sample closer than this, in scene units (0 = its tangent-plane patch; paper: 0.001)",
       &LdcConfig::hitDistance, "0.001"},
  };
  return params;
}

}  // namespace lt
