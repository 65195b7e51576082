// The DDS configuration a participant starts from (configs/dds/*.xml).
#pragma once

#include <string>

namespace ignav::protocol {

// Reads a Cyclone configuration file's text; throws DdsError (errors.hpp) naming the file.
std::string readConfigFile(const std::string& path);

}  // namespace ignav::protocol
