#include "static_files.hpp"

#include <cctype>

namespace ignav::web {

namespace fs = std::filesystem;

std::string contentType(const fs::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json" || ext == ".map") return "application/json";
  if (ext == ".png") return "image/png";
  if (ext == ".svg") return "image/svg+xml";
  return "application/octet-stream";
}

std::optional<fs::path> staticFile(const fs::path& root, std::string_view target) {
  target = target.substr(0, target.find('?'));
  if (target.empty() || target.front() != '/') return std::nullopt;
  if (target == "/") target = "/index.html";
  for (const char c : target) {
    const bool plain =
        std::isalnum(static_cast<unsigned char>(c)) || c == '/' || c == '.' || c == '-' || c == '_';
    if (!plain) return std::nullopt;
  }
  if (target.find("/.") != std::string_view::npos) return std::nullopt;
  return root / fs::path(std::string(target.substr(1)));
}

}  // namespace ignav::web
