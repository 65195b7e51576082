// The session's seeds as dosimetry sees them, shared by plan_seeds' job (seed_planning.cpp) and
// compute_dose's (dose_computation.cpp): structures as voxel centres, the seed a needle leaves at
// a target, the seeds a confirmation CT found, a request with the site's dose limits.
#pragma once

#include <vector>

#include "ignav/dosimetry/seed_plan.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::workflow {

dosimetry::DoseStructure doseStructure(const anatomy::Structure& s);

// The seed a needle leaves at a target: at the target, along the needle's last step.
dosimetry::Seed seedAt(const Session& s, const Target& t);

// The seeds the confirmation CT found (tips and rejected ones left out), in the planning CT's
// frame, each along the robot's insertion axis there (a found seed's own orientation is not
// measured).
std::vector<dosimetry::Seed> implantedSeeds(const Session& s);

// `ask`'s seed model tabulated, `target` and every avoided structure with the site's dose limits;
// no candidates. Errors: the model's file, named.
Expected<dosimetry::SeedPlanRequest> doseRequest(const Session& s, const SeedPlanAsk& ask,
                                                 const anatomy::Structure& target);

}  // namespace ignav::workflow
