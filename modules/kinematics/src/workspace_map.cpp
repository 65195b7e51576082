#include "ignav/kinematics/workspace_map.hpp"

#include <cmath>
#include <cstdio>

namespace ignav::kinematics {

double WorkspaceMap::sampledVolume_cm3() const {
  return static_cast<double>(points_mm.size()) * grid_mm * grid_mm * grid_mm / 1000.0;
}

Expected<WorkspaceMap> computeWorkspaceMap(const Kinematics& k, double grid_mm) {
  if (!(grid_mm >= 0.05 && grid_mm <= 10.0)) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "grid_mm = %g is outside [0.05, 10] mm", grid_mm);
    return makeError(ErrorCode::kInvalidArgument, buf);
  }
  WorkspaceMap map;
  map.grid_mm = grid_mm;
  const double r_min = k.minRadius_mm(), r_max = k.maxRadius_mm();
  const double zc_max = k.instrument().cannula_travel_mm;
  const auto n = static_cast<long>(std::floor(r_max / grid_mm));
  const double expected = k.workspace().volume_exact_cm3 * 1000.0 / (grid_mm * grid_mm * grid_mm);
  map.points_mm.reserve(static_cast<size_t>(expected * 1.05) + 16);
  map.z_s_mm.reserve(map.points_mm.capacity());
  // The tip radius depends on z_s alone and z_c only shifts z, so one radial solve per (x, y)
  // column gives the column's whole reachable z interval [z0 - zc_max, z0].
  for (long ix = -n; ix <= n; ++ix) {
    const double x = static_cast<double>(ix) * grid_mm;
    for (long iy = -n; iy <= n; ++iy) {
      const double y = static_cast<double>(iy) * grid_mm;
      const double r = std::hypot(x, y);
      if (r < r_min || r > r_max) continue;
      const double zs = k.styletForRadius_mm(r);
      const double z_top = k.tipDepthAtHome_mm(zs);
      const double z_bottom = z_top - zc_max;
      const auto iz_lo = static_cast<long>(std::ceil(z_bottom / grid_mm));
      const auto iz_hi = static_cast<long>(std::floor(z_top / grid_mm));
      for (long iz = iz_lo; iz <= iz_hi; ++iz) {
        map.points_mm.emplace_back(static_cast<float>(x), static_cast<float>(y),
                                   static_cast<float>(static_cast<double>(iz) * grid_mm));
        map.z_s_mm.push_back(static_cast<float>(zs));
      }
    }
  }
  return map;
}

}  // namespace ignav::kinematics
