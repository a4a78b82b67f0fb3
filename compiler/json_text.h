// JSON string quoting shared by reliefc's JSON diagnostics and relief's statistics. Header-only, so
// that relief, which links no part of the compiler, can use it.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

#include "compiler/utf8.h"

namespace relief::compiler {

// Valid UTF-8 passes through; each byte of an invalid sequence (a Latin-1 file name, a stray
// byte in a source line) becomes U+FFFD, so that every line stays valid JSON.
inline std::string jsonQuoted(std::string_view s) {
  std::string out = "\"";
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\n': out += "\\n"; break;
        case '\t': out += "\\t"; break;
        default:
          if (c < 0x20 || c == 0x7f) {
            char escaped[8];
            std::snprintf(escaped, sizeof escaped, "\\u%04x", c);
            out += escaped;
          } else {
            out += char(c);
          }
      }
      ++i;
      continue;
    }
    uint32_t code = 0;
    if (const int length = utf8Sequence(s.data() + i, s.data() + s.size(), &code)) {
      out.append(s.substr(i, size_t(length)));
      i += size_t(length);
    } else {
      out += "\\ufffd";
      ++i;
    }
  }
  return out + "\"";
}

}  // namespace relief::compiler
