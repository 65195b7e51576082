// The XML of COMMAND and RTS_COMMAND as OpenIGTLinkIO, Slicer's OpenIGTLinkRemote and PLUS write
// it: one element whose attributes are the command's arguments (<Command Name="START_UP" />), and
// the answer's Status ("SUCCESS" | "FAIL") and Message. Read with expat (well-formedness checked,
// no entities expanded beyond XML's five, no external anything). Pure.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "ignav/core/expected.hpp"

namespace ignav::igtl {

using XmlAttributes = std::vector<std::pair<std::string, std::string>>;

struct CommandXml {
  std::string element;  // the root element's name ("Command")
  XmlAttributes attributes;
  const std::string* attribute(const std::string& name) const;
};

// The root element and its attributes. Errors (kFormat) say what is wrong and where (line,
// column), or that a document type is not accepted.
Expected<CommandXml> parseCommandXml(std::string_view text);

// <element a="..." b="..." />, values escaped.
std::string writeCommandXml(const std::string& element, const XmlAttributes& attributes);

}  // namespace ignav::igtl
