// David Clunie's DICOM validator, dciodvfy (Debian's dicom3tools), for tests that check what
// ignav writes (RT Plan, RT Dose) against the IODs.
#pragma once

#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "support/command_output.hpp"

namespace ignav::test {

// dciodvfy's findings that are errors (it prints "Error - ..." lines; warnings are left), or what
// it said when it did not check the file as the IOD named (a line with the IOD's name ends a
// check it finished).
inline std::vector<std::string> iodErrors(const std::string& path, const std::string& iod) {
  std::vector<std::string> errors;
  const std::string said = commandOutput("dciodvfy -new " + path + " 2>&1; true");
  std::istringstream lines(said);
  bool checked = false;
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("Error", 0) == 0) errors.push_back(line);
    checked = checked || line == iod;
  }
  if (!checked) errors.push_back("not checked as " + iod + ": " + said);
  return errors;
}

// A copy of an RT Dose that dciodvfy can read: 16 bits allocated (dicom3tools asserts on 32), the
// frames' count doubled to match the pixel data's length; every other attribute as written.
inline std::string readableByDciodvfy(const std::string& dose_path) {
  const std::string copy = dose_path + ".16bit.dcm";
  std::filesystem::copy_file(dose_path, copy, std::filesystem::copy_options::overwrite_existing);
  const std::string frames = commandOutput("dcmdump +P NumberOfFrames " + dose_path);
  const auto open = frames.find('['), close = frames.find(']');
  const int n = std::stoi(frames.substr(open + 1, close - open - 1));
  commandOutput(
      fmt::format("dcmodify -nb -m '(0028,0100)=16' -m '(0028,0101)=16' -m "
                  "'(0028,0102)=15' -m '(0028,0008)={}' {}",
                  2 * n, copy));
  return copy;
}

}  // namespace ignav::test
