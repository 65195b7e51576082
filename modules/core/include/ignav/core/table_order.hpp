// Tables declared in the order of their enum (row i describes enumerator i: the command table, the
// reply codes, the background job kinds), so that a lookup by enum is an index. A row out of
// place would give one entry another's name and rules: a constexpr table is checked when compiling
// (static_assert), a runtime one's accessor refuses to run.
#pragma once

#include <cstddef>
#include <vector>

namespace ignav {

template <typename Row, typename Enum>
bool inEnumOrder(const std::vector<Row>& rows, Enum Row::*key) {
  for (std::size_t i = 0; i < rows.size(); ++i)
    if (static_cast<std::size_t>(rows[i].*key) != i) return false;
  return true;
}

template <typename Row, std::size_t N, typename Enum>
constexpr bool inEnumOrder(const Row (&rows)[N], Enum Row::*key) {
  for (std::size_t i = 0; i < N; ++i)
    if (static_cast<std::size_t>(rows[i].*key) != i) return false;
  return true;
}

}  // namespace ignav
