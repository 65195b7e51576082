// Instruments the kinematics tests share: the paper's, and variants that stress each term.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "ignav/config/robot_config.hpp"
#include "ignav/kinematics/solver.hpp"

namespace ignav::kinematics::testing {

inline Instrument paperInstrument() {
  return config::loadRobotConfig(std::string(IGNAV_SOURCE_DIR) + "/configs/robots/torabi2014.yaml")
      .value()
      .instrument;
}

struct NamedInstrument {
  std::string name;
  Instrument instrument;
};

// Lateral, axial and no offset; Rd = 200, 550, ∞; L0 > zs_max — MODEL.md §6.1's sweep.
inline std::vector<NamedInstrument> variedInstruments() {
  std::vector<NamedInstrument> out;
  const Instrument paper = paperInstrument();
  out.push_back({"paper_lateral", paper});
  Instrument g = paper;
  g.exit_offset = ExitOffset::kAxial;
  out.push_back({"axial", g});
  g.exit_offset = ExitOffset::kNone;
  out.push_back({"no_offset", g});
  g = paper;
  g.cannula_deflected_radius_mm = 200.0;
  out.push_back({"rd200", g});
  g.cannula_deflected_radius_mm = std::numeric_limits<double>::infinity();
  out.push_back({"rigid", g});
  g = paper;
  g.stylet_curved_length_mm = 45.0;
  out.push_back({"l0_45", g});
  g = paper;
  g.stylet_radius_mm = 55.0;
  g.stylet_outer_diameter_mm = 0.5;
  g.cannula_inner_diameter_mm = 2.4;
  g.cannula_outer_diameter_mm = 2.7;
  out.push_back({"wide_clearance_r55", g});
  return out;
}

}  // namespace ignav::kinematics::testing
