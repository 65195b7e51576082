// The browser app's files as the gateway serves them over HTTP: which file a request names (plain
// names under the app folder only) and its content type.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace ignav::web {

std::string contentType(const std::filesystem::path& file);

// The file under `root` that a request target names, or nullopt. Only plain names: no "..", no
// percent-escapes, no hidden files, so that nothing outside the app folder is ever served.
std::optional<std::filesystem::path> staticFile(const std::filesystem::path& root,
                                                std::string_view target);

}  // namespace ignav::web
