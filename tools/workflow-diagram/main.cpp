// Prints docs/WORKFLOW.md from the workflow's transition table:
//   build/tools/workflow-diagram/ignav-workflow-diagram > docs/WORKFLOW.md
// A test fails when the checked-in file differs.
#include <iostream>

#include "ignav/workflow/reducer.hpp"

int main() {
  std::cout << ignav::workflow::workflowMarkdown();
  return 0;
}
