// A beam pushed into a Winkler foundation that remembers the channel its tip cut (rod_world.hpp).
#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "ignav/needle_world/rod_world.hpp"

namespace ignav::needle_world {
namespace {

double stiffnessAt(const std::vector<TissueLayer>& layers, double depth_mm) {
  double k = 0.0;  // above the first layer: air
  for (const auto& layer : layers)
    if (depth_mm >= layer.from_depth_mm) k = layer.stiffness_n_per_mm2;
  return k;
}

}  // namespace

BeamDeviation pushBeam(double ei_nmm2, double tip_force_n, double length_mm, double depth0_mm,
                       double step_mm, const std::vector<TissueLayer>& layers) {
  BeamDeviation out;
  if (!(length_mm > 0.0)) {
    out.lateral_mm.assign(1, 0.0);
    return out;
  }
  const int nodes = std::max(1, static_cast<int>(std::ceil(length_mm / step_mm - 1e-9)));
  const double h = length_mm / nodes;
  // The channel: where the tip was when it reached each node's depth (the tissue's rest position
  // there); springs pull the beam back towards it.
  std::vector<double> channel(static_cast<std::size_t>(nodes) + 1, 0.0);
  Eigen::VectorXd w;
  int n = 0;
  for (n = 1; n <= nodes; ++n) {
    // Unknowns w_{−1} .. w_{n+2} (ghost nodes at both ends) at columns 0 .. n+3.
    const int size = n + 4;
    auto col = [](int i) { return i + 1; };
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(size, size);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(size);
    a(0, col(0)) = 1.0;  // clamped where it enters: w(0) = 0 ...
    a(1, col(-1)) = 1.0;
    a(1, col(1)) = -1.0;  // ... and w'(0) = 0
    // EI w'''' + k (w − channel) = 0 at nodes 1 .. n, each row divided by EI / h⁴. The tip's own
    // node is freshly cut: no spring yet.
    const double scale = std::pow(h, 4) / ei_nmm2;
    for (int i = 1; i <= n; ++i) {
      const int row = 1 + i;
      const double k = i < n ? stiffnessAt(layers, depth0_mm + i * h) * scale : 0.0;
      a(row, col(i - 2)) += 1.0;
      a(row, col(i - 1)) += -4.0;
      a(row, col(i)) += 6.0 + k;
      a(row, col(i + 1)) += -4.0;
      a(row, col(i + 2)) += 1.0;
      b(row) = k * channel[static_cast<std::size_t>(i)];
    }
    // The free tip: no moment (w'' = 0), and the shear the force makes (EI w''' = −F).
    a(n + 2, col(n - 1)) = 1.0;
    a(n + 2, col(n)) = -2.0;
    a(n + 2, col(n + 1)) = 1.0;
    a(n + 3, col(n + 2)) = 1.0;
    a(n + 3, col(n + 1)) = -2.0;
    a(n + 3, col(n - 1)) = 2.0;
    a(n + 3, col(n - 2)) = -1.0;
    b(n + 3) = -2.0 * std::pow(h, 3) * tip_force_n / ei_nmm2;
    w = a.partialPivLu().solve(b);
    channel[static_cast<std::size_t>(n)] = w(col(n));
  }
  n = nodes;
  out.lateral_mm.resize(static_cast<std::size_t>(nodes) + 1);
  for (int i = 0; i <= nodes; ++i)
    out.lateral_mm[static_cast<std::size_t>(i)] = w(i + 1);
  out.tip_angle_rad = std::atan((w(n + 2) - w(n)) / (2.0 * h));
  return out;
}

}  // namespace ignav::needle_world
