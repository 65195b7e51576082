// Text helpers shared by the NRRD and MetaImage header parsers (module-private).
#pragma once

#include <cctype>
#include <initializer_list>
#include <istream>
#include <string>
#include <utility>
#include <vector>

#include "ignav/core/expected.hpp"

namespace ignav::volume::header_text {

inline Error fail(ErrorCode code, const std::string& what, const std::string& problem) {
  return makeError(code, what + ": " + problem);
}

inline std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

// At most 60 characters of a header line for a message, binary bytes shown as '?'.
inline std::string printable(const std::string& s) {
  std::string out = s.substr(0, 60);
  for (auto& c : out) {
    if (!std::isprint(static_cast<unsigned char>(c))) c = '?';
  }
  return out;
}

inline std::string lower(std::string s) {
  for (auto& c : s)
    c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

inline bool readLine(std::istream& in, std::string& line, std::size_t max_chars) {
  line.clear();
  for (int c = in.get(); c != EOF; c = in.get()) {
    if (c == '\n') return true;
    if (line.size() >= max_chars) return false;
    line += static_cast<char>(c);
  }
  return !line.empty();
}

// Header fields in file order with lower-cased names; the first of `names` present wins.
struct HeaderFields {
  std::vector<std::pair<std::string, std::string>> entries;

  void add(std::string key, std::string value) {
    entries.emplace_back(std::move(key), std::move(value));
  }
  const std::string* find(std::initializer_list<const char*> names) const {
    for (const auto& [k, v] : entries) {
      for (const char* name : names) {
        if (k == name) return &v;
      }
    }
    return nullptr;
  }
};

inline Error missingField(const std::string& what, const char* field) {
  return fail(ErrorCode::kFormat, what, std::string("missing field '") + field + "'");
}

}  // namespace ignav::volume::header_text
