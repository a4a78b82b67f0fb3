// UTF-8 decoding shared by the lexer (invalid characters), the caret line of text diagnostics and
// JSON quoting: one definition of what a well-formed sequence is.
#pragma once

#include <cstdint>

namespace relief::compiler {

// Length (2 to 4) of the well-formed UTF-8 sequence at p, with its code point in *cp; 0 if the
// bytes are not one (ASCII, a stray continuation byte, an overlong form, a surrogate, a truncation).
inline int utf8Sequence(const char* p, const char* end, uint32_t* cp) {
  const auto byte = [&](int i) { return static_cast<unsigned char>(p[i]); };
  const unsigned char lead = byte(0);
  int len = 0;
  uint32_t min = 0;
  if (lead >= 0xC2 && lead <= 0xDF) len = 2, min = 0x80, *cp = lead & 0x1F;
  else if (lead >= 0xE0 && lead <= 0xEF) len = 3, min = 0x800, *cp = lead & 0x0F;
  else if (lead >= 0xF0 && lead <= 0xF4) len = 4, min = 0x10000, *cp = lead & 0x07;
  else return 0;
  if (end - p < len) return 0;
  for (int i = 1; i < len; ++i) {
    if ((byte(i) & 0xC0) != 0x80) return 0;
    *cp = (*cp << 6) | (byte(i) & 0x3F);
  }
  if (*cp < min || *cp > 0x10FFFF || (*cp >= 0xD800 && *cp <= 0xDFFF)) return 0;
  return len;
}

}  // namespace relief::compiler
