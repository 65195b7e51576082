// load_structures' background job (background_jobs.hpp): read the segmentation, check it was
// made on the session's CT, give the site's roles, build a distance field per structure.
#include <fmt/format.h>

#include <memory>

#include "ignav/anatomy/dicom_structures.hpp"
#include "ignav/anatomy/distance_field.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/workflow/background_jobs.hpp"

namespace ignav::workflow {

namespace {

// "prostate (target, 1234 voxels, 5.67 cm³); urethra (avoid 3 mm, ...); NOTES".
std::string describeStructures(const anatomy::StructureSet& set) {
  std::string out;
  for (const auto& s : set.structures) {
    out += fmt::format("{}{} ({}{}, {} voxels, {:.2f} cm³)", out.empty() ? "" : "; ", s.name,
                       anatomy::toString(s.role),
                       s.role == anatomy::Role::kAvoid ? fmt::format(" {:g} mm", s.margin_mm) : "",
                       s.mask.count(), s.mask.volume_cm3());
  }
  for (const auto& note : set.notes)
    out += "; " + note;
  return out;
}

anatomy::CtFrame ctFrame(const LoadedCt& ct) {
  return {ct.volume->geometry, ct.volume->frame_of_reference_uid, ct.source};
}

// The built-in phantom's anatomy on its CT: drawn where the phantom put the robot.
Expected<anatomy::StructureSet> phantomStructures(const LoadedCt& ct, const config::Robot& robot,
                                                  const JobContext& context) {
  if (ct.source != kPhantomSource) {
    return makeError(ErrorCode::kInvalidArgument,
                     "phantom: structures belong to the built-in phantom CT (load phantom:); the "
                     "CT loaded is " +
                         ct.source,
                     "other_ct");
  }
  auto rp = registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan);
  if (!rp) return rp.error();
  auto set = anatomy::voxelise(ct.volume->geometry, rp->image_to_robot_true,
                               phantomAnatomy(robot.kinematics), kPhantomSource);
  if (set && !context.session_dir.empty()) {
    // For people and other tools (3D Slicer opens the segmentation over the phantom's series,
    // SlicerRT and planning systems the structure set); a failure here loses nothing.
    (void)anatomy::writeSegNrrd(*set, ct.volume->geometry,
                                (context.session_dir / "phantom_anatomy.seg.nrrd").string());
    anatomy::RtStructureSetHeader header;
    header.label = "ignav phantom anatomy";
    header.patient_name = "IGNAV^PHANTOM";
    header.patient_id = "IGNAV-PHANTOM";
    header.referenced_series_uid = ct.volume->series_uid;
    (void)anatomy::writeRtStructureSet(
        *set, ctFrame(ct), header, (context.session_dir / "phantom_anatomy_rtstruct.dcm").string());
  }
  return set;
}

}  // namespace

Input loadStructures(std::uint64_t job, const std::string& source, const LoadedCt& ct,
                     const std::optional<anatomy::Site>& site, const config::Robot& robot,
                     const JobContext& context) {
  Input in;
  in.job = job;
  in.path = source;
  in.kind = InputKind::kStructuresLoadFailed;
  if (!ct.volume) {
    in.error = "no CT is loaded: structures belong to one";
    return in;
  }
  auto read = source == kPhantomSource ? phantomStructures(ct, robot, context)
                                       : anatomy::readStructures(source, ctFrame(ct));
  if (!read) {
    in.error = read.error().message;
    return in;
  }
  if (auto on_ct = anatomy::checkOnCt(*read, ct.volume->geometry, ct.source); !on_ct.ok()) {
    in.error = on_ct.error().message;
    return in;
  }
  if (site) anatomy::applySite(*site, *read);
  auto set = std::make_shared<const anatomy::StructureSet>(std::move(read).value());
  // One field after another on this thread: with two cores, a second thread here would take
  // the core the event thread answers commands on (the fields of five structures of a 512 x 512 x
  // 300 CT take ~0.15 s; PERFORMANCE.md).
  const std::size_t total = set->structures.size();
  for (std::size_t n = 0; n < total; ++n) {
    if (context.progress) context.progress(n, total);
    in.structures.fields.push_back(std::make_shared<const anatomy::DistanceField>(
        anatomy::DistanceField::fromMask(set->structures[n].mask, kStructureReach_mm)));
  }
  if (context.progress) context.progress(total, total);
  in.summary = describeStructures(*set);
  in.structures.set = std::move(set);
  in.kind = InputKind::kStructuresLoaded;
  return in;
}

}  // namespace ignav::workflow
