#include <gtest/gtest.h>

#include "ignav/kinematics/ik_study.hpp"

namespace ignav::kinematics {
namespace {

// MODEL.md §7 ran the paper's simulation with an independent implementation; these are its
// figures (mean, max, variance, geometries with mean < 0.60 mm).
struct Reference {
  ExitOffset offset;
  double mean, max, var;
  size_t below;
};

class IkStudy : public ::testing::TestWithParam<Reference> {};

TEST_P(IkStudy, ReproducesTheModelFigures) {
  const Reference ref = GetParam();
  const IkStudyResult r = runIkStudy({"", ref.offset, 550.0, 40.0, 40.0});
  EXPECT_EQ(r.geometries.size(), 64u);
  EXPECT_NEAR(static_cast<double>(r.targets), 200000.0, 40000.0);  // "about 200k targets"
  EXPECT_NEAR(r.mean_mm, ref.mean, 0.01);
  EXPECT_NEAR(r.max_mm, ref.max, 0.01);
  EXPECT_NEAR(r.variance_mm2, ref.var, 0.01);
  EXPECT_EQ(r.geometriesWithMeanBelow(0.60), ref.below);
  // 1.1-2.1 % of targets get out-of-range closed-form joints.
  const double clipped = static_cast<double>(r.clipped) / static_cast<double>(r.targets);
  EXPECT_GT(clipped, 0.005);
  EXPECT_LT(clipped, 0.03);
  // The exact solver is exact on every target of every geometry.
  EXPECT_LT(r.exact_max_mm, 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Model, IkStudy,
                         ::testing::Values(Reference{ExitOffset::kNone, 0.86, 4.47, 0.69, 20},
                                           Reference{ExitOffset::kLateral, 0.66, 3.78, 0.45, 41},
                                           Reference{ExitOffset::kAxial, 1.08, 4.52, 0.57, 7}),
                         [](const auto& p) { return std::string(toString(p.param.offset)); });

}  // namespace
}  // namespace ignav::kinematics
