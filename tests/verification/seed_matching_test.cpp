// Matching seeds to targets: closer together than the targeting error, ambiguous, too many,
// none; against hand-made cases and brute force over permutations.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

#include "ignav/verification/seed_matching.hpp"

namespace ignav::verification {
namespace {

using Points = std::vector<Eigen::Vector3d>;

std::vector<TargetPoint> row(int n, double spacing_mm) {
  std::vector<TargetPoint> t;
  for (int i = 0; i < n; ++i)
    t.push_back({static_cast<std::uint32_t>(i + 1), Eigen::Vector3d(spacing_mm * i, 0.0, -150.0)});
  return t;
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(SeedMatching, SeedsCloserTogetherThanTheErrorStillMatchTheirTargets) {
  // Five targets 2 mm apart; every seed landed 2.5 mm off along the row (a tissue pushing the
  // needle one way), with ±0.2 mm scatter. Each seed lies 0.5 mm from its neighbour's target, so
  // a nearest-target rule pairs all but one wrongly; the total squared distance is least for the
  // true pairs by 2·(2 mm)² = 8 mm² per exchanged neighbour pair.
  const auto targets = row(5, 2.0);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> scatter(-0.2, 0.2);
  Points seeds;
  for (const auto& t : targets) {
    seeds.push_back(t.mm + Eigen::Vector3d(2.5 + scatter(rng), scatter(rng), scatter(rng)));
  }
  std::vector<std::size_t> order{3, 0, 4, 1, 2};  // seeds found in another order
  Points shuffled;
  for (auto s : order)
    shuffled.push_back(seeds[s]);
  // The nearest-target rule really is wrong here.
  std::size_t nearest_wrong = 0;
  for (std::size_t s = 0; s < 4; ++s) {
    if ((seeds[s] - targets[s + 1].mm).norm() < (seeds[s] - targets[s].mm).norm()) ++nearest_wrong;
  }
  ASSERT_EQ(nearest_wrong, 4u);

  auto m = matchSeeds(targets, shuffled);
  ASSERT_TRUE(m.ok()) << m.error().message;
  for (std::size_t i = 0; i < targets.size(); ++i) {
    ASSERT_TRUE(m->targets[i].seed.has_value());
    EXPECT_EQ(order[*m->targets[i].seed], i) << "target " << targets[i].id;
    EXPECT_NEAR(m->targets[i].distance_mm, (seeds[i] - targets[i].mm).norm(), 1e-12);
    EXPECT_GT(m->targets[i].runner_up_margin_sd, 3.0);
  }
  EXPECT_TRUE(m->missing_targets.empty());
  EXPECT_TRUE(m->extra_seeds.empty());
}

TEST(SeedMatching, ExchangingTwoNeighboursCostsWhatTheClosedFormSays) {
  // Two targets 2 mm apart, both seeds shifted by the same 2.5 mm: exchanging them changes the
  // total squared distance by 2 (s1 - s2)·(t1 - t2) = 2 · 4 = 8 mm², and its SD under a
  // localisation SD σ is σ·|2(t1 - t2)|·√2 = σ · 4√2 mm².
  const auto targets = row(2, 2.0);
  const Eigen::Vector3d shift(1.5, 2.0, 0.0);  // |shift| = 2.5
  const Points seeds{targets[0].mm + shift, targets[1].mm + shift};
  MatchOptions o;
  o.localisation_sd_mm = 0.3;
  auto m = matchSeeds(targets, seeds, o);
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_EQ(m->targets[0].runner_up_seed, std::optional<std::size_t>(1));
  EXPECT_NEAR(m->targets[0].runner_up_extra_mm2, 8.0, 1e-9);
  EXPECT_NEAR(m->targets[0].runner_up_margin_sd, 8.0 / (0.3 * 4.0 * std::sqrt(2.0)), 1e-9);
  // With a worse localisation the same pair is no longer told apart.
  o.localisation_sd_mm = 0.8;  // 8 / (0.8 · 5.66) = 1.8 SD < 3
  auto refused = matchSeeds(targets, seeds, o);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().reason, "ambiguous_match");
}

TEST(SeedMatching, AnAmbiguousMatchIsRefusedWithTheTargetsAndSeedsNamed) {
  // Two seeds symmetric about the line through two targets: either way round costs the same.
  const auto targets = row(2, 2.0);
  const Points seeds{{1.0, 1.5, -150.0}, {1.0, -1.5, -150.0}};
  auto m = matchSeeds(targets, seeds);
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().reason, "ambiguous_match");
  EXPECT_EQ(m.error().code, ErrorCode::kDegenerate);
  const auto& msg = m.error().message;
  EXPECT_TRUE(contains(msg, "target 1")) << msg;
  EXPECT_TRUE(contains(msg, "target 2")) << msg;
  EXPECT_TRUE(contains(msg, "seed 1 at (1.00, 1.50, -150.00)")) << msg;
  EXPECT_TRUE(contains(msg, "0.00 mm²")) << msg;
}

TEST(SeedMatching, MoreSeedsThanTargetsIsAnErrorNamingTheLeftOverSeed) {
  const auto targets = row(3, 6.0);
  Points seeds;
  for (const auto& t : targets)
    seeds.push_back(t.mm + Eigen::Vector3d(0.3, -0.4, 0.5));
  seeds.insert(seeds.begin() + 1, Eigen::Vector3d(40.0, 40.0, -150.0));  // seed 2: a stray one
  auto m = matchSeeds(targets, seeds);
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().reason, "more_seeds_than_targets");
  EXPECT_TRUE(contains(m.error().message, "4 seeds for 3 targets")) << m.error().message;
  EXPECT_TRUE(contains(m.error().message, "seed 2 at (40.00, 40.00, -150.00)"))
      << m.error().message;

  MatchOptions allow;
  allow.allow_extra_seeds = true;
  auto ok = matchSeeds(targets, seeds, allow);
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_EQ(ok->extra_seeds, (std::vector<std::size_t>{1}));
  EXPECT_TRUE(ok->missing_targets.empty());
}

TEST(SeedMatching, NoSeedsNoTargetsAndBadInputAreClearErrors) {
  auto none = matchSeeds(row(4, 5.0), {});
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.error().reason, "no_seeds");
  EXPECT_TRUE(contains(none.error().message, "4 targets")) << none.error().message;
  auto no_targets = matchSeeds({}, Points{{0, 0, 0}});
  ASSERT_FALSE(no_targets.ok());
  EXPECT_EQ(no_targets.error().reason, "no_targets");
  auto dup = row(2, 5.0);
  dup[1].id = 1;
  EXPECT_EQ(matchSeeds(dup, Points{{0, 0, 0}}).error().reason, "duplicate_target");
  EXPECT_EQ(matchSeeds(row(2, 5.0), Points{{std::nan(""), 0, 0}}).error().reason, "non_finite");
  MatchOptions bad;
  bad.max_distance_mm = 0.0;
  auto b = matchSeeds(row(2, 5.0), Points{{0, 0, 0}}, bad);
  ASSERT_FALSE(b.ok());
  EXPECT_EQ(b.error().reason, "bad_option");
  EXPECT_TRUE(contains(b.error().message, "max_distance_mm")) << b.error().message;
}

TEST(SeedMatching, ASeedBeyondTheCredibleDistanceLeavesItsTargetMissing) {
  const auto targets = row(3, 8.0);
  Points seeds{targets[0].mm + Eigen::Vector3d(1, 0, 0), targets[2].mm + Eigen::Vector3d(0, 1, 0),
               targets[1].mm + Eigen::Vector3d(0, 0, 14.0)};  // 14 mm: dropped elsewhere
  auto m = matchSeeds(targets, seeds);
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_EQ(m->missing_targets, (std::vector<std::size_t>{1}));
  EXPECT_EQ(m->extra_seeds, (std::vector<std::size_t>{2}));
  EXPECT_EQ(m->targets[0].seed, std::optional<std::size_t>(0));
  EXPECT_EQ(m->targets[2].seed, std::optional<std::size_t>(1));
  EXPECT_TRUE(std::isnan(m->targets[1].distance_mm));
  EXPECT_TRUE(contains(m->summary, "no seed within 10 mm of target(s) 2")) << m->summary;
}

TEST(SeedMatching, TheAssignmentIsTheLeastTotalSquaredDistanceOverAllPermutations) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  std::normal_distribution<double> err(0.0, 1.5);
  for (int trial = 0; trial < 200; ++trial) {
    const std::size_t n = 2 + static_cast<std::size_t>(trial % 5);
    std::vector<TargetPoint> targets;
    Points seeds;
    for (std::size_t i = 0; i < n; ++i) {
      targets.push_back(
          {static_cast<std::uint32_t>(10 + i), Eigen::Vector3d(u(rng), u(rng), u(rng))});
      seeds.push_back(targets.back().mm + Eigen::Vector3d(err(rng), err(rng), err(rng)));
    }
    MatchOptions o;
    o.max_distance_mm = 1000.0;  // every pair credible: a plain permutation problem
    o.min_margin_sd = 0.0;       // report, never refuse (ties aside)
    auto m = matchSeeds(targets, seeds, o);
    ASSERT_TRUE(m.ok()) << m.error().message;
    std::vector<std::size_t> perm(n);
    std::iota(perm.begin(), perm.end(), 0);
    double best = INFINITY;
    do {
      double sum = 0.0;
      for (std::size_t i = 0; i < n; ++i)
        sum += (seeds[perm[i]] - targets[i].mm).squaredNorm();
      best = std::min(best, sum);
    } while (std::next_permutation(perm.begin(), perm.end()));
    EXPECT_NEAR(m->total_squared_distance_mm2, best, 1e-9) << "trial " << trial;
  }
}

}  // namespace
}  // namespace ignav::verification
