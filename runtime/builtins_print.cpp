// printf()/format()/concat() for shaders (see builtins_print.h). Supports %d %i %f %g %e %s %% and
// RSL's %p %c %m, with optional flags/width/precision; triples and matrices print all components
// separated by spaces.
#include "runtime/builtins_print.h"

#include <cstdio>
#include <deque>
#include <string>

namespace {

std::string formatText(const char* format, const int32_t* kinds, int32_t count, const float* floats,
                       const int32_t* ints, const char* const* strings) {
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
    } else if (conv == 'f' || conv == 'g' || conv == 'e' || conv == 'd' || conv == 'i' || conv == 'p' ||
               conv == 'c' || conv == 'm') {
      // RSL's %p (point), %c (color) and %m (matrix) print every component as %f does.
      const char c = (conv == 'd' || conv == 'i') ? 'g' : (conv == 'p' || conv == 'c' || conv == 'm') ? 'f' : conv;
      const int n = kind == kRlfPrintTriple ? 3 : kind == kRlfPrintMatrix ? 16 : 1;
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
      else fi += kind == kRlfPrintTriple ? 3 : kind == kRlfPrintMatrix ? 16 : 1;
    }
  }
  return out;
}

// Strings built at run time, per thread, freed per shading point. The cap bounds what a hostile
// loop of concat() calls can allocate before the loop guard stops it.
constexpr size_t kMaxArenaBytes = size_t(16) << 20;
struct StringArena {
  std::deque<std::string> strings;
  size_t bytes = 0;
};
thread_local StringArena arena;

const char* keep(std::string s) {
  if (arena.bytes + s.size() > kMaxArenaBytes) return "";
  arena.bytes += s.size();
  return arena.strings.emplace_back(std::move(s)).c_str();
}

}  // namespace

extern "C" void rlf_printf(const RlfHostServices* services, const char* format, const int32_t* kinds, int32_t count,
                           const float* floats, const int32_t* ints, const char* const* strings) {
  if (!services || !services->print || !format) return;
  try {
    services->print(services->context, formatText(format, kinds, count, floats, ints, strings).c_str());
  } catch (...) {
    // Nothing may unwind through JIT frames; a lost debug message is acceptable.
  }
}

extern "C" const char* rlf_format(const char* format, const int32_t* kinds, int32_t count, const float* floats,
                                  const int32_t* ints, const char* const* strings) {
  if (!format) return "";
  try {
    return keep(formatText(format, kinds, count, floats, ints, strings));
  } catch (...) {
    return "";  // out of memory: an empty string rather than unwinding through JIT frames
  }
}

extern "C" const char* rlf_concat(const char* const* parts, int32_t count) {
  try {
    std::string out;
    for (int32_t i = 0; i < count; ++i)
      if (parts[i]) out += parts[i];
    return keep(std::move(out));
  } catch (...) {
    return "";
  }
}

extern "C" void rlf_strings_reset(void) {
  arena.strings.clear();
  arena.bytes = 0;
}
