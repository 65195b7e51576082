// The 3D view's scene (issue 43; SceneRequest -> SceneReply, docs/PROTOCOL.md), made on the
// slices thread from a snapshot of the session: the CT averaged down to at most 256 voxels a side
// and sent by slabs of at most 8 MiB, and the surfaces (the structures', the feasible volume's,
// the latest dose's isodoses) made once per change and kept until the next.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/protocol/types.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::server {

// Where the scene's surfaces go when another edge asked for them (OpenIGTLink's POLYDATA): called
// on the slices thread with them, or with why not.
using SurfacesDone = std::function<void(Expected<std::vector<protocol::SceneSurface>>)>;

class SceneBuilder {
 public:
  static constexpr std::uint32_t kDefaultVoxelsPerAxis = 256;
  static constexpr std::uint32_t kMinVoxelsPerAxis = 16, kMaxVoxelsPerAxis = 1024;
  static constexpr std::size_t kMaxSlabBytes = std::size_t{8} << 20;

  // The reply to `request` from `session` (client and request ids included); never throws for
  // bad input: the reply says what is wrong.
  protocol::SceneReply build(const protocol::SceneRequest& request,
                             const workflow::Session& session);
  // The surfaces alone (structures, feasible volume, isodoses; LPS), the same kept meshes: what
  // OpenIGTLink's POLYDATA carries.
  std::vector<protocol::SceneSurface> surfaces(const workflow::Session& session);

 private:
  struct Averaged {  // the CT averaged over blocks of voxels
    std::uint32_t max_per_axis = 0;
    std::array<std::uint32_t, 3> dims{};
    Eigen::Matrix4d ijk_to_lps = Eigen::Matrix4d::Identity();
    std::vector<std::int16_t> voxels;  // empty: blocks of one voxel, the CT's own voxels
  };
  static Averaged averagedOf(const volume::Volume& ct, std::uint32_t max);
  void volumePart(const protocol::SceneRequest& request, const workflow::Session& session,
                  protocol::SceneReply& out);
  void surfacesPart(const workflow::Session& session, protocol::SceneReply& out);
  const std::vector<protocol::SceneSurface>& structureSurfaces(const workflow::Session& session);
  const std::vector<protocol::SceneSurface>& feasibleSurface(const workflow::Session& session);
  const std::vector<protocol::SceneSurface>& isodoseSurfaces(const workflow::Session& session);

  // Each kept with what it was made of: a shared pointer keeps its source alive, so an address
  // is never reused for another while it is compared.
  std::shared_ptr<const volume::Volume> averaged_of_;
  Averaged averaged_;
  std::shared_ptr<const anatomy::StructureSet> structures_of_;
  std::vector<protocol::SceneSurface> structures_;
  std::shared_ptr<const config::Robot> feasible_robot_;
  Eigen::Matrix4d feasible_registration_ = Eigen::Matrix4d::Zero();
  std::vector<protocol::SceneSurface> feasible_;
  std::shared_ptr<const std::vector<float>> isodose_of_;
  double isodose_rx_Gy_ = 0.0;
  std::vector<protocol::SceneSurface> isodoses_;
};

}  // namespace ignav::server
