// printf() formatting for shaders (see builtins_print.h). Supports %d %i %f %g %e %s %% with
// optional flags/width/precision; triples print all three components separated by spaces.
#include "runtime/builtins_print.h"

#include <cstdio>
#include <string>

extern "C" void rlf_printf(const RlfHostServices* services, const char* format, const int32_t* kinds, int32_t count,
                           const float* floats, const int32_t* ints, const char* const* strings) {
  if (!services || !services->print || !format) return;
  try {
    std::string out;
    int arg = 0, fi = 0, ii = 0, si = 0;
    char buf[128];
    for (const char* p = format; *p; ++p) {
      if (*p != '%') {
        out += *p;
        continue;
      }
      if (p[1] == '%') {
        out += '%';
        ++p;
        continue;
      }
      // Copy the conversion spec (flags, width, precision) up to its letter.
      std::string spec = "%";
      const char* q = p + 1;
      while (*q && std::string("-+ #0123456789.").find(*q) != std::string::npos && spec.size() < 16) spec += *q++;
      const char conv = *q;
      if (!conv) break;
      p = q;
      if (arg >= count) {
        out += spec + conv;  // more conversions than arguments: print the spec verbatim
        continue;
      }
      const int kind = kinds[arg++];
      if (conv == 's' && kind == kRlfPrintString) {
        std::snprintf(buf, sizeof buf, (spec + 's').c_str(), strings[si] ? strings[si] : "");
        ++si;
        out += buf;
      } else if ((conv == 'd' || conv == 'i') && kind == kRlfPrintInt) {
        std::snprintf(buf, sizeof buf, (spec + 'd').c_str(), ints[ii++]);
        out += buf;
      } else if (conv == 'f' || conv == 'g' || conv == 'e' || conv == 'd' || conv == 'i') {
        const char c = (conv == 'd' || conv == 'i') ? 'g' : conv;
        const int n = kind == kRlfPrintTriple ? 3 : 1;
        for (int k = 0; k < n; ++k) {
          double v = kind == kRlfPrintInt ? double(ints[ii]) : double(floats[fi + k]);
          std::snprintf(buf, sizeof buf, (spec + c).c_str(), v);
          if (k) out += ' ';
          out += buf;
        }
        if (kind == kRlfPrintInt) ++ii; else if (kind != kRlfPrintString) fi += n; else ++si;
      } else {
        out += spec + conv;
        if (kind == kRlfPrintInt) ++ii;
        else if (kind == kRlfPrintString) ++si;
        else fi += kind == kRlfPrintTriple ? 3 : 1;
      }
    }
    services->print(services->context, out.c_str());
  } catch (...) {
    // Nothing may unwind through JIT frames; a lost debug message is acceptable.
  }
}
