// The linear assignment problem: give each row its own column so that the summed cost is least
// (Kuhn–Munkres / Hungarian method with potentials, O(rows²·cols)), and, for each row, the
// cheapest assignment in which that row gets a different column: how distinct the optimum is.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"

namespace ignav::verification {

struct Assignment {
  std::vector<std::size_t> column_of_row;
  double cost = 0.0;  // the sum of cost(row, column_of_row[row])
};

struct AssignmentWithAlternatives {
  Assignment best;
  // Per row: the cheapest assignment in which this row's column differs from best's (its cost
  // is best.cost + how much that choice is worse), or none when every such assignment uses a
  // forbidden pair.
  std::vector<std::optional<Assignment>> alternative;
};

// cost: rows <= cols; +infinity forbids a pair. Errors: more rows than columns, a NaN or -inf
// cost (invalid_argument), no assignment without a forbidden pair (degenerate, "infeasible").
Expected<Assignment> minimumCostAssignment(const Eigen::MatrixXd& cost);

// The same optimum and the alternative per row: one Dijkstra search per row over the reduced
// costs that the optimum's potentials leave (an alternative differs from the optimum by one
// cycle of exchanged columns), O(n³) in all.
Expected<AssignmentWithAlternatives> assignWithAlternatives(const Eigen::MatrixXd& cost);

}  // namespace ignav::verification
