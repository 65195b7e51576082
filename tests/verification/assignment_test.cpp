// The assignment solver against brute force: every injective assignment enumerated.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "ignav/verification/assignment.hpp"

namespace ignav::verification {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Least cost over all injective row -> column maps, optionally with row `pinned_row` kept off
// column `avoid` (kInf when none exists).
double bruteForce(const Eigen::MatrixXd& cost, Eigen::Index pinned_row = -1,
                  Eigen::Index avoid = -1) {
  const Eigen::Index rows = cost.rows(), cols = cost.cols();
  std::vector<Eigen::Index> col(static_cast<std::size_t>(rows));
  std::vector<bool> used(static_cast<std::size_t>(cols), false);
  double best = kInf;
  auto go = [&](auto&& self, Eigen::Index r, double sum) -> void {
    if (r == rows) {
      best = std::min(best, sum);
      return;
    }
    for (Eigen::Index c = 0; c < cols; ++c) {
      if (used[static_cast<std::size_t>(c)] || (r == pinned_row && c == avoid)) continue;
      used[static_cast<std::size_t>(c)] = true;
      self(self, r + 1, sum + cost(r, c));
      used[static_cast<std::size_t>(c)] = false;
    }
  };
  go(go, 0, 0.0);
  return best;
}

TEST(Assignment, OptimumAndEveryRowsRunnerUpEqualBruteForce) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(0.0, 10.0);
  std::uniform_int_distribution<int> size(1, 6);
  for (int trial = 0; trial < 400; ++trial) {
    const int rows = size(rng);
    const int cols = rows + std::uniform_int_distribution<int>(0, 2)(rng);
    Eigen::MatrixXd cost(rows, cols);
    for (int i = 0; i < rows; ++i)
      for (int j = 0; j < cols; ++j)
        cost(i, j) = (trial % 3 == 0 && u(rng) < 2.0) ? kInf : u(rng);
    const double reference = bruteForce(cost);
    auto plain = minimumCostAssignment(cost);
    auto with = assignWithAlternatives(cost);
    if (!std::isfinite(reference)) {
      ASSERT_FALSE(plain.ok()) << "trial " << trial;
      EXPECT_EQ(plain.error().reason, "infeasible");
      EXPECT_FALSE(with.ok());
      continue;
    }
    ASSERT_TRUE(plain.ok()) << plain.error().message;
    ASSERT_TRUE(with.ok()) << with.error().message;
    EXPECT_NEAR(plain->cost, reference, 1e-9) << "trial " << trial;
    EXPECT_NEAR(with->best.cost, reference, 1e-9) << "trial " << trial;
    // The columns are distinct and the cost is what they add up to.
    double sum = 0.0;
    std::vector<bool> seen(static_cast<std::size_t>(cols), false);
    for (int i = 0; i < rows; ++i) {
      const auto c = with->best.column_of_row[static_cast<std::size_t>(i)];
      ASSERT_FALSE(seen[c]);
      seen[c] = true;
      sum += cost(i, static_cast<Eigen::Index>(c));
    }
    EXPECT_NEAR(sum, with->best.cost, 1e-9);
    for (int r = 0; r < rows; ++r) {
      const auto avoid =
          static_cast<Eigen::Index>(with->best.column_of_row[static_cast<std::size_t>(r)]);
      const double runner_up = bruteForce(cost, r, avoid);
      const auto& alt = with->alternative[static_cast<std::size_t>(r)];
      if (!std::isfinite(runner_up)) {
        EXPECT_FALSE(alt.has_value()) << "trial " << trial << " row " << r;
        continue;
      }
      ASSERT_TRUE(alt.has_value()) << "trial " << trial << " row " << r;
      EXPECT_NEAR(alt->cost, runner_up, 1e-9) << "trial " << trial << " row " << r;
      EXPECT_NE(static_cast<Eigen::Index>(alt->column_of_row[static_cast<std::size_t>(r)]), avoid);
    }
  }
}

TEST(Assignment, TextbookThreeByThree) {
  // By hand: 1 + 2 + 2 = 5; every other permutation costs 6 or more.
  Eigen::MatrixXd cost(3, 3);
  cost << 4, 1, 3,  //
      2, 0, 5,      //
      3, 2, 2;
  auto a = minimumCostAssignment(cost);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->column_of_row, (std::vector<std::size_t>{1, 0, 2}));
  EXPECT_DOUBLE_EQ(a->cost, 5.0);
}

TEST(Assignment, BadInputIsRefusedWithTheReason) {
  EXPECT_FALSE(minimumCostAssignment(Eigen::MatrixXd::Zero(3, 2)).ok());
  Eigen::MatrixXd nan = Eigen::MatrixXd::Zero(2, 2);
  nan(1, 0) = std::nan("");
  auto e = minimumCostAssignment(nan);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().message.find("cost(1, 0)"), std::string::npos) << e.error().message;
  Eigen::MatrixXd blocked = Eigen::MatrixXd::Constant(2, 2, kInf);
  blocked(0, 0) = blocked(1, 0) = 1.0;  // both rows can only take column 0
  auto b = minimumCostAssignment(blocked);
  ASSERT_FALSE(b.ok());
  EXPECT_EQ(b.error().reason, "infeasible");
  EXPECT_TRUE(minimumCostAssignment(Eigen::MatrixXd(0, 0)).ok());
}

}  // namespace
}  // namespace ignav::verification
