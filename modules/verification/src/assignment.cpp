#include "ignav/verification/assignment.hpp"

#include <cmath>
#include <limits>
#include <string>

namespace ignav::verification {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();

Status checkCost(const Eigen::MatrixXd& cost) {
  if (cost.rows() > cost.cols()) {
    return makeError(ErrorCode::kInvalidArgument,
                     "assignment: " + std::to_string(cost.rows()) + " rows but only " +
                         std::to_string(cost.cols()) + " columns: every row needs its own column");
  }
  for (Eigen::Index i = 0; i < cost.rows(); ++i) {
    for (Eigen::Index j = 0; j < cost.cols(); ++j) {
      const double c = cost(i, j);
      if (std::isnan(c) || c == -kInf) {
        return makeError(ErrorCode::kInvalidArgument, "assignment: cost(" + std::to_string(i) +
                                                          ", " + std::to_string(j) +
                                                          ") is NaN or -infinity");
      }
    }
  }
  return Ok{};
}

// The solution with its potentials: cost(i, j) - u[i] - v[j] >= 0 everywhere, = 0 on the
// assignment (up to rounding).
struct Solved {
  Assignment assignment;
  std::vector<double> u, v;
};

// Kuhn–Munkres with potentials, one row added at a time along a shortest augmenting path
// (the e-maxx formulation); indices from 1, column 0 is the path's virtual root.
Expected<Solved> hungarian(const Eigen::MatrixXd& cost) {
  const auto n = static_cast<std::size_t>(cost.rows());
  const auto m = static_cast<std::size_t>(cost.cols());
  std::vector<double> u(n + 1, 0.0), v(m + 1, 0.0), minv(m + 1);
  std::vector<std::size_t> p(m + 1, 0), way(m + 1, 0);
  std::vector<char> used(m + 1);
  auto a = [&](std::size_t i, std::size_t j) {
    return cost(static_cast<Eigen::Index>(i - 1), static_cast<Eigen::Index>(j - 1));
  };
  for (std::size_t i = 1; i <= n; ++i) {
    p[0] = i;
    std::size_t j0 = 0;
    std::fill(minv.begin(), minv.end(), kInf);
    std::fill(used.begin(), used.end(), 0);
    do {
      used[j0] = 1;
      const std::size_t i0 = p[j0];
      double delta = kInf;
      std::size_t j1 = kNone;
      for (std::size_t j = 1; j <= m; ++j) {
        if (used[j]) continue;
        const double cur = a(i0, j) - u[i0] - v[j];
        if (cur < minv[j]) {
          minv[j] = cur;
          way[j] = j0;
        }
        if (minv[j] < delta) {
          delta = minv[j];
          j1 = j;
        }
      }
      if (j1 == kNone) {
        return makeError(ErrorCode::kDegenerate,
                         "assignment: row " + std::to_string(i - 1) +
                             " cannot be given a column without a forbidden pair",
                         "infeasible");
      }
      for (std::size_t j = 0; j <= m; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    do {
      const std::size_t j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0 != 0);
  }
  Solved s;
  s.assignment.column_of_row.assign(n, kNone);
  for (std::size_t j = 1; j <= m; ++j) {
    if (p[j] != 0) s.assignment.column_of_row[p[j] - 1] = j - 1;
  }
  for (std::size_t i = 0; i < n; ++i) {
    s.assignment.cost += cost(static_cast<Eigen::Index>(i),
                              static_cast<Eigen::Index>(s.assignment.column_of_row[i]));
  }
  s.u.assign(u.begin() + 1, u.end());
  s.v.assign(v.begin() + 1, v.end());
  return s;
}

}  // namespace

Expected<Assignment> minimumCostAssignment(const Eigen::MatrixXd& cost) {
  if (auto ok = checkCost(cost); !ok) return ok.error();
  if (cost.rows() == 0) return Assignment{};
  auto solved = hungarian(cost);
  if (!solved) return solved.error();
  return std::move(solved->assignment);
}

Expected<AssignmentWithAlternatives> assignWithAlternatives(const Eigen::MatrixXd& cost) {
  if (auto ok = checkCost(cost); !ok) return ok.error();
  const auto rows = static_cast<std::size_t>(cost.rows());
  const auto n = static_cast<std::size_t>(cost.cols());
  AssignmentWithAlternatives out;
  if (rows == 0) return out;
  // Square: the columns no row takes go to zero-cost padding rows, so that a row moving to a
  // free column is a cycle like any other (the padding row takes the column it left).
  Eigen::MatrixXd square =
      Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  square.topRows(cost.rows()) = cost;
  auto solved = hungarian(square);
  if (!solved) return solved.error();
  const auto& col = solved->assignment.column_of_row;
  std::vector<std::size_t> row_of_col(n);
  for (std::size_t i = 0; i < n; ++i)
    row_of_col[col[i]] = i;
  auto reduced = [&](std::size_t i, std::size_t j) {
    const double c = square(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) -
                     solved->u[i] - solved->v[j];
    return c < 0.0 ? 0.0 : c;  // rounding; exact potentials leave none negative
  };
  out.best.column_of_row.assign(col.begin(), col.begin() + static_cast<std::ptrdiff_t>(rows));
  out.best.cost = solved->assignment.cost;  // the padding rows cost nothing
  out.alternative.resize(rows);
  std::vector<double> dist(n);
  std::vector<std::size_t> prev(n);
  std::vector<char> done(n);
  for (std::size_t r = 0; r < rows; ++r) {
    // Row r leaves its column: the shortest path over columns, each step handing a column to
    // the row that held the previous one, back to the column r left.
    const std::size_t target = col[r];
    for (std::size_t j = 0; j < n; ++j) {
      dist[j] = j == target ? kInf : reduced(r, j);
      prev[j] = kNone;
      done[j] = 0;
    }
    bool closed = false;
    for (;;) {
      std::size_t c = kNone;
      double best = kInf;
      for (std::size_t j = 0; j < n; ++j) {
        if (!done[j] && dist[j] < best) {
          best = dist[j];
          c = j;
        }
      }
      if (c == kNone) break;
      done[c] = 1;
      if (c == target) {
        closed = true;
        break;
      }
      const std::size_t i = row_of_col[c];
      for (std::size_t j = 0; j < n; ++j) {
        if (done[j] || j == c) continue;
        const double d = best + reduced(i, j);
        if (d < dist[j]) {
          dist[j] = d;
          prev[j] = c;
        }
      }
    }
    if (!closed) continue;
    std::vector<std::size_t> alt = col;
    for (std::size_t c = target;;) {
      const std::size_t from = prev[c];
      if (from == kNone) {
        alt[r] = c;
        break;
      }
      alt[row_of_col[from]] = c;
      c = from;
    }
    Assignment a;
    a.column_of_row.assign(alt.begin(), alt.begin() + static_cast<std::ptrdiff_t>(rows));
    for (std::size_t i = 0; i < rows; ++i) {
      a.cost += cost(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(alt[i]));
    }
    out.alternative[r] = std::move(a);
  }
  return out;
}

}  // namespace ignav::verification
