#include "ignav/igtl/command_xml.hpp"

#include <expat.h>
#include <fmt/format.h>

#include <memory>

namespace ignav::igtl {
namespace {

struct ParseState {
  CommandXml out;
  int depth = 0;
  bool doctype = false;
};

void XMLCALL onStart(void* user, const XML_Char* name, const XML_Char** attributes) {
  auto* state = static_cast<ParseState*>(user);
  if (state->depth++ > 0) return;  // children (a reply's <Result>) are not arguments
  state->out.element = name;
  for (int i = 0; attributes[i] != nullptr; i += 2)
    state->out.attributes.emplace_back(attributes[i], attributes[i + 1]);
}

void XMLCALL onEnd(void* user, const XML_Char*) {
  --static_cast<ParseState*>(user)->depth;
}

// A DOCTYPE could declare entities (billion laughs): a command has none, so any is refused.
void XMLCALL onDoctype(void* user, const XML_Char*, const XML_Char*, const XML_Char*, int) {
  static_cast<ParseState*>(user)->doctype = true;
}

}  // namespace

const std::string* CommandXml::attribute(const std::string& name) const {
  for (const auto& [key, value] : attributes) {
    if (key == name) return &value;
  }
  return nullptr;
}

Expected<CommandXml> parseCommandXml(std::string_view text) {
  if (text.size() > 1024 * 1024) {
    return makeError(ErrorCode::kFormat,
                     fmt::format("command XML of {} bytes; at most 1 MiB", text.size()));
  }
  std::unique_ptr<XML_ParserStruct, decltype(&XML_ParserFree)> parser(XML_ParserCreate("UTF-8"),
                                                                      &XML_ParserFree);
  if (!parser) return makeError(ErrorCode::kInternal, "cannot create an XML parser");
  ParseState state;
  XML_SetUserData(parser.get(), &state);
  XML_SetElementHandler(parser.get(), onStart, onEnd);
  XML_SetStartDoctypeDeclHandler(parser.get(), onDoctype);
  const bool ok =
      XML_Parse(parser.get(), text.data(), static_cast<int>(text.size()), 1) == XML_STATUS_OK;
  if (state.doctype) {
    return makeError(ErrorCode::kFormat,
                     "command XML: a document type declaration is not accepted");
  }
  if (!ok) {
    return makeError(ErrorCode::kFormat,
                     fmt::format("command XML: {} at line {}, column {}",
                                 XML_ErrorString(XML_GetErrorCode(parser.get())),
                                 XML_GetCurrentLineNumber(parser.get()),
                                 XML_GetCurrentColumnNumber(parser.get()) + 1));
  }
  return std::move(state.out);
}

std::string writeCommandXml(const std::string& element, const XmlAttributes& attributes) {
  std::string out = "<" + element;
  for (const auto& [key, value] : attributes) {
    out += " " + key + "=\"";
    for (const char c : value) {
      switch (c) {
        case '&':
          out += "&amp;";
          break;
        case '<':
          out += "&lt;";
          break;
        case '>':
          out += "&gt;";
          break;
        case '"':
          out += "&quot;";
          break;
        case '\n':
          out += "&#10;";
          break;
        default:
          out += c;
      }
    }
    out += "\"";
  }
  return out + " />";
}

}  // namespace ignav::igtl
