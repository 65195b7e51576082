// The rest of an insertion re-aimed from the needle's shape on an intermittent CT
// (compensation.hpp, reaimFromPath).
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include <Eigen/Geometry>

#include "ignav/compensation/compensation.hpp"
#include "polyline.hpp"

namespace ignav::compensation {
namespace {

constexpr double kPairStep_mm = 1.0;  // observed points kept about every millimetre of arc
constexpr double kMinPath_mm = 3.0;
constexpr int kIterations = 100;

}  // namespace

Expected<Reaim> reaimFromPath(const kinematics::Kinematics& kinematics,
                              const DeflectionModel& model, const kinematics::Joints& partial,
                              const std::vector<Eigen::Vector3d>& observed_path_mm,
                              const Eigen::Vector3d& target_mm,
                              const CompensationOptions& options) {
  const bool finite = std::all_of(observed_path_mm.begin(), observed_path_mm.end(),
                                  [](const Eigen::Vector3d& p) { return p.allFinite(); });
  if (!finite || !target_mm.allFinite()) {
    return makeError(ErrorCode::kInvalidArgument,
                     "re-aim: the observed path and the target must be finite");
  }
  const double observed_mm = detail::polylineLength(observed_path_mm);
  if (observed_path_mm.size() < 4 || observed_mm < kMinPath_mm) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("re-aim: the observed path has {} points over {:.2f} mm: at least "
                                 "4 over {} mm are needed to see how the needle went",
                                 observed_path_mm.size(), observed_mm, kMinPath_mm),
                     "path_too_short");
  }
  auto predicted = predictPath(kinematics, model, partial, 0.25, 0.0);
  if (!predicted) return predicted.error();
  std::vector<Eigen::Vector3d> line = predicted->cannula_mm;
  line.insert(line.end(), predicted->stylet_mm.begin(), predicted->stylet_mm.end());
  // The motion by iterated closest points: each observed point paired with the nearest point of
  // the moved model path, the tips paired with the weight of a quarter of the path (a nearly
  // straight needle would otherwise slide along itself), Eigen::umeyama (no scale) each round.
  const std::vector<Eigen::Vector3d> observed =
      detail::thinnedFromTip(observed_path_mm, kPairStep_mm);
  const auto n = static_cast<Eigen::Index>(observed.size());
  const Eigen::Index tip_weight = std::max<Eigen::Index>(1, n / 4);
  Eigen::Matrix3Xd from(3, n + tip_weight), to(3, n + tip_weight);
  for (Eigen::Index k = 0; k < tip_weight; ++k) {
    from.col(n + k) = line.back();
    to.col(n + k) = observed.back();
  }
  Eigen::Matrix4d motion = Eigen::Matrix4d::Identity();
  for (int round = 0; round < kIterations; ++round) {
    const Eigen::Matrix4d back = motion.inverse();
    for (Eigen::Index k = 0; k < n; ++k) {
      const Eigen::Vector3d q = observed[static_cast<std::size_t>(k)];
      from.col(k) = detail::nearestOnPolyline(line, (back * q.homogeneous()).head<3>());
      to.col(k) = q;
    }
    const Eigen::Matrix4d next = Eigen::umeyama(from, to, false);
    const bool settled = (next - motion).cwiseAbs().maxCoeff() < 1e-10;
    motion = next;
    if (settled) break;
  }
  Reaim out;
  out.pairs = static_cast<std::size_t>(n);
  out.correction = motion;
  out.tip_offset_mm = (observed_path_mm.back() - line.back()).norm();
  const Eigen::Matrix3Xd carried =
      (motion.topLeftCorner<3, 3>() * from.leftCols(n)).colwise() + motion.topRightCorner<3, 1>();
  out.path_rms_mm = std::sqrt((carried - to.leftCols(n)).colwise().squaredNorm().mean());
  // Aim the model at the target carried back, so that the corrected landing is the target.
  const Eigen::Matrix4d back = out.correction.inverse();
  const Eigen::Vector3d aim = (back * target_mm.homogeneous()).head<3>();
  auto aimed = compensate(kinematics, model, aim, options);
  if (!aimed) return aimed.error();
  out.aimed = *aimed;
  out.landing_mm = (out.correction * aimed->compensated_landing_mm.homogeneous()).head<3>();
  return out;
}

}  // namespace ignav::compensation
