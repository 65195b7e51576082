// compute_dose's job (background_jobs.hpp): the dose of the plan's targets as seeds and of the
// seeds a confirmation CT found, on the CT's voxels around the structure dosed; the metrics on
// every voxel of the structures; the files a person, 3D Slicer or a planning system opens.
#include <fmt/format.h>

#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>

#include "ignav/anatomy/dicom_structures.hpp"
#include "ignav/dosimetry/dose_nrrd.hpp"
#include "ignav/dosimetry/dvh_plot.hpp"
#include "ignav/dosimetry/rt_dose.hpp"
#include "ignav/dosimetry/rt_plan.hpp"
#include "ignav/workflow/background_jobs.hpp"
#include "session_seeds.hpp"

namespace ignav::workflow {
namespace {

namespace fs = std::filesystem;

// The CT's voxels within kDoseMargin_mm of the structure's box: the dose's grid, aligned with the
// CT so that a DVH tool samples the dose where the structures' voxels are.
volume::Geometry doseGrid(const volume::Geometry& ct, const anatomy::Mask& structure) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& corner : structure.corners()) {
    const Eigen::Vector3d ijk = ct.toIjk(corner);
    lo = lo.cwiseMin(ijk);
    hi = hi.cwiseMax(ijk);
  }
  volume::Geometry grid = ct;
  std::array<int, 3> from{};
  for (int a = 0; a < 3; ++a) {
    const double margin = std::ceil(kDoseMargin_mm / ct.spacing_mm[a]);
    from[a] = std::max(0, static_cast<int>(std::floor(lo[a] + 1e-6 - margin)));
    const int to = std::min(ct.dims[a] - 1, static_cast<int>(std::ceil(hi[a] - 1e-6 + margin)));
    grid.dims[a] = std::max(1, to - from[a] + 1);
  }
  grid.origin_lps_mm = ct.toLps(Eigen::Vector3d(from[0], from[1], from[2]));
  return grid;
}

// `unix_s` (the server's stamp on the input that asked) as UTC in `format`.
std::string utc(double unix_s, const char* format) {
  const auto t = static_cast<std::time_t>(unix_s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, format, &tm);
  return buf;
}

// The colours of the DVH plot: the structures' own.
volume::Rgb colourOf(const anatomy::StructureSet& set, const std::string& name) {
  const auto* s = set.find(name);
  auto channel = [](double c) { return static_cast<std::uint8_t>(std::lround(255.0 * c)); };
  if (!s) return {0, 0, 0};
  return {channel(s->colour_rgb[0]), channel(s->colour_rgb[1]), channel(s->colour_rgb[2])};
}

// Into <session>/dose/: the structures, the plan(s), each dose as RT Dose and NRRD, the DVHs as a
// plot and a table. A file that cannot be written is said in the result; the dose stands.
std::vector<std::string> writeDoseFiles(const Session& s, const ComputedDose& dose,
                                        const std::vector<std::vector<dosimetry::Seed>>& seeds,
                                        const dosimetry::SeedModel& model, const fs::path& dir,
                                        std::vector<std::string>& problems) {
  std::vector<std::string> files;
  std::error_code ec;
  fs::create_directories(dir / "dose", ec);
  if (ec) {
    problems.push_back(fmt::format("cannot create {}: {}", (dir / "dose").string(), ec.message()));
    return files;
  }
  auto note = [&](const Status& written, const std::string& file) {
    if (written.ok())
      files.push_back(file);
    else
      problems.push_back(written.error().message);
  };
  const volume::Volume& ct = *s.ct.volume;
  const std::string study = ct.study_uid.empty() ? dosimetry::newDicomUid() : ct.study_uid;
  anatomy::RtStructureSetHeader structures;
  structures.label = "ignav structures";
  structures.patient_name = ct.patient_name;
  structures.patient_id = ct.patient_id;
  structures.study_uid = study;
  structures.referenced_series_uid = ct.series_uid;
  structures.sop_instance_uid = dosimetry::newDicomUid();
  note(anatomy::writeRtStructureSet(*s.structures.loaded.set,
                                    {ct.geometry, ct.frame_of_reference_uid, s.ct.source},
                                    structures, (dir / "dose/structures_rtstruct.dcm").string()),
       "dose/structures_rtstruct.dcm");
  const double rx = dose.seeds.prescription_Gy;
  std::vector<dosimetry::DvhCurve> curves;
  for (std::size_t n = 0; n < dose.doses.size(); ++n) {
    const SeedDose& d = dose.doses[n];
    const std::string what = d.what;
    const std::string plan_uid = dosimetry::newDicomUid();
    if (!seeds[n].empty()) {
      dosimetry::RtPlanHeader plan;
      plan.sop_instance_uid = plan_uid;
      plan.frame_of_reference_uid = ct.frame_of_reference_uid;
      plan.study_uid = study;
      plan.patient_name = ct.patient_name;
      plan.patient_id = ct.patient_id;
      plan.label = what == "planned" ? "ignav planned" : "ignav implanted";
      plan.structure_set_uid = structures.sop_instance_uid;
      plan.date_yyyymmdd = utc(s.dose.asked_s, "%Y%m%d");
      plan.time_hhmmss = utc(s.dose.asked_s, "%H%M%S");
      note(dosimetry::writeSeedRtPlan(seeds[n], model, dose.seeds.strength_U, rx, plan,
                                      (dir / ("dose/" + what + "_rtplan.dcm")).string()),
           "dose/" + what + "_rtplan.dcm");
    }
    dosimetry::RtDoseHeader header;
    header.frame_of_reference_uid = ct.frame_of_reference_uid;
    header.study_uid = study;
    header.patient_name = ct.patient_name;
    header.patient_id = ct.patient_id;
    header.comment =
        fmt::format("ignav TG-43U1 {} dose, {} seeds of {}", what, d.seeds, dose.seeds.seed_model);
    header.plan_uid = seeds[n].empty() ? "" : plan_uid;
    note(dosimetry::writeRtDose(*d.dose_Gy, dose.grid, header,
                                (dir / ("dose/" + what + "_rtdose.dcm")).string()),
         "dose/" + what + "_rtdose.dcm");
    note(dosimetry::writeDoseNrrd(*d.dose_Gy, dose.grid,
                                  (dir / ("dose/" + what + "_dose.nrrd")).string()),
         "dose/" + what + "_dose.nrrd");
    for (const auto& c : d.evaluation.curves) {
      curves.push_back({fmt::format("{} ({})", c.name, what),
                        colourOf(*s.structures.loaded.set, c.name), what == "delivered",
                        dosimetry::kCurveBin_Gy, c.cumulative});
    }
  }
  if (auto png = dosimetry::dvhPlotPng(curves, rx); png.ok()) {
    std::ofstream out(dir / "dose/dvh.png", std::ios::binary);
    out.write(reinterpret_cast<const char*>(png->data()),
              static_cast<std::streamsize>(png->size()));
    if (out)
      files.push_back("dose/dvh.png");
    else
      problems.push_back((dir / "dose/dvh.png").string() + ": cannot be written");
  } else {
    problems.push_back(png.error().message);
  }
  // The curves as a table: one column per structure and dose, one row per Gy.
  std::ofstream csv(dir / "dose/dvh.csv");
  std::size_t rows = 0;
  csv << "dose_Gy";
  for (const auto& c : curves) {
    csv << ",\"" << c.name << " (%)\"";
    rows = std::max(rows, c.cumulative.size());
  }
  csv << "\n";
  for (std::size_t k = 0; k < rows; ++k) {
    csv << fmt::format("{:g}", dosimetry::kCurveBin_Gy * static_cast<double>(k));
    for (const auto& c : curves)
      csv << fmt::format(",{:.3f}", 100.0 * (k < c.cumulative.size() ? c.cumulative[k] : 0.0));
    csv << "\n";
  }
  if (csv)
    files.push_back("dose/dvh.csv");
  else
    problems.push_back((dir / "dose/dvh.csv").string() + ": cannot be written");
  return files;
}

std::string describe(const SeedDose& d) {
  std::string out = fmt::format("{} ({} seeds): {}", d.what, d.seeds, d.evaluation.describe());
  if (!d.cold_spots.empty()) {
    out += fmt::format("; {} cold spot{}, the largest {:.2f} cm³", d.cold_spots.size(),
                       d.cold_spots.size() == 1 ? "" : "s", d.cold_spots.front().volume_cm3);
  }
  return out;
}

}  // namespace

Input computeDose(std::uint64_t job, const std::shared_ptr<const Session>& snapshot,
                  const JobContext& context) {
  const Session& s = *snapshot;
  Input in;
  in.job = job;
  in.kind = InputKind::kDoseFailed;
  const auto& asked = s.dose;
  const auto* set = s.structures.loaded.set.get();
  const anatomy::Structure* target = set ? set->find(asked.structure) : nullptr;
  if (!asked.seeds || !target || !s.ct.volume) {
    in.error =
        fmt::format("no structure '{}' on the session's CT to judge the dose on", asked.structure);
    return in;
  }
  const SeedPlanAsk& ask = *asked.seeds;
  auto request = doseRequest(s, ask, *target);
  if (!request) {
    in.error = request.error().message;
    return in;
  }
  // As they were when the dose was asked: planned, a seed at each plannable target; delivered,
  // those the confirmation CT found.
  std::vector<std::string> whats;
  std::vector<std::vector<dosimetry::Seed>> seeds;
  for (const auto& [what, these] : {std::pair{"planned", &asked.planned_seeds},
                                    std::pair{"delivered", &asked.delivered_seeds}}) {
    if (these->empty()) continue;
    whats.push_back(what);
    seeds.push_back(*these);
  }
  if (seeds.empty()) {
    in.error = "no seeds: no target was plannable, and no confirmation CT found any";
    return in;
  }
  auto dose = std::make_shared<ComputedDose>();
  dose->seeds = ask;
  dose->structure = target->name;
  dose->grid = doseGrid(s.ct.volume->geometry, target->mask);
  const auto& table = *request->table;
  // Gy of the permanent implant per cGy h⁻¹ of initial rate.
  const double gy_per_rate =
      dosimetry::permanentImplantDose_cGy(1.0, table.model().half_life_h) / 100.0;
  const std::size_t total = 2 * seeds.size();
  for (std::size_t n = 0; n < seeds.size(); ++n) {
    if (context.progress) context.progress(2 * n, total);
    // One thread: the job thread's (the other core answers commands).
    auto rate = dosimetry::doseRateOnGrid(table, seeds[n], ask.strength_U, dose->grid, 1);
    for (auto& v : rate)
      v = static_cast<float>(v * gy_per_rate);
    if (context.progress) context.progress(2 * n + 1, total);
    SeedDose d;
    d.what = whats[n];
    d.seeds = seeds[n].size();
    d.dose_Gy = std::make_shared<const std::vector<float>>(std::move(rate));
    auto evaluation = dosimetry::evaluatePlan(*request, seeds[n]);
    auto cold = dosimetry::coldSpots(*request, seeds[n]);
    if (!evaluation || !cold) {
      in.error = (!evaluation ? evaluation.error() : cold.error()).message;
      return in;
    }
    d.evaluation = std::move(evaluation).value();
    d.cold_spots = std::move(cold).value();
    dose->doses.push_back(std::move(d));
  }
  in.summary = fmt::format("dose of {} at {:g} U for {:g} Gy to '{}' on {} x {} x {} voxels",
                           ask.seed_model, ask.strength_U, ask.prescription_Gy, target->name,
                           dose->grid.dims[0], dose->grid.dims[1], dose->grid.dims[2]);
  for (const auto& d : dose->doses)
    in.summary += "; " + describe(d);
  if (!context.session_dir.empty()) {
    std::vector<std::string> problems;
    dose->files = writeDoseFiles(s, *dose, seeds, table.model(), context.session_dir, problems);
    in.error = fmt::format("{}", fmt::join(problems, "; "));  // what was not written, if any
  }
  if (context.progress) context.progress(total, total);
  in.dose = std::move(dose);
  in.kind = InputKind::kDoseComputed;
  return in;
}

}  // namespace ignav::workflow
