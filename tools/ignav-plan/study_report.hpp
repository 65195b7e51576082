// Writes the IK study (MODEL.md §7) as Markdown and PNG figures.
#pragma once

#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/kinematics/ik_study.hpp"

namespace ignav::plan {

struct StudyReport {
  std::vector<kinematics::IkStudyResult> sets;
  std::vector<kinematics::IkStudySample> experiment_map;  // the paper's instrument
  std::string robot_name;
};

// out_dir/IK_STUDY.md, out_dir/ik_study_heatmap.png, out_dir/ik_study_histogram.png
Status writeStudyReport(const StudyReport& report, const std::string& out_dir);

}  // namespace ignav::plan
