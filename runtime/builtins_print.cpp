// printf()/format()/concat() for shaders (see builtins_print.h). Supports %d %i %f %g %e %s %% and
// RSL's %p %c %m, with optional flags/width/precision; triples and matrices print all components
// separated by spaces.
#include "runtime/builtins_print.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <string>

namespace {

// snprintf of one conversion into `out`, at any length (a fixed buffer cut long strings short).
template <typename T>
void appendFormatted(std::string& out, const std::string& spec, T value) {
  char small[128];
  const int n = std::snprintf(small, sizeof small, spec.c_str(), value);
  if (n < 0) return;
  if (size_t(n) < sizeof small) {
    out.append(small, size_t(n));
    return;
  }
  std::string big(size_t(n) + 1, '\0');
  std::snprintf(big.data(), big.size(), spec.c_str(), value);
  out.append(big.data(), size_t(n));
}

// Field widths and precisions past kMaxField are taken as kMaxField: "%999999999f" made snprintf
// write a gigabyte per conversion at every shaded point (the render hung at 2 GB).
constexpr long kMaxField = 1024;
std::string clampWidths(const std::string& spec) {
  std::string out;
  for (size_t i = 0; i < spec.size();) {
    if (spec[i] < '1' || spec[i] > '9') {
      out += spec[i++];
      continue;
    }
    size_t j = i;
    while (j < spec.size() && spec[j] >= '0' && spec[j] <= '9') ++j;
    const std::string digits = spec.substr(i, j - i);
    out += digits.size() > 4 || std::stol(digits) > kMaxField ? std::to_string(kMaxField) : digits;
    i = j;
  }
  return out;
}

std::string formatText(const char* format, const int32_t* kinds, int32_t count, const float* floats,
                       const int32_t* ints, const char* const* strings) {
  std::string out;
  int arg = 0, fi = 0, ii = 0, si = 0;
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
    spec = clampWidths(spec);
    const char conv = *q;
    if (!conv) break;
    p = q;
    if (arg >= count) {
      out += spec + conv;  // more conversions than arguments: print the spec verbatim
      continue;
    }
    const int kind = kinds[arg++];
    const int n = kind == kRlfPrintTriple ? 3 : kind == kRlfPrintMatrix ? 16 : kind == kRlfPrintString ? 0 : 1;
    // The argument's own text, whatever the conversion asked for: a string as it is, numbers as
    // %g (components separated by spaces). A mismatch (which the compiler warns about where the
    // format is a literal) prints the value rather than whatever memory the conversion would read.
    auto plain = [&] {
      std::string text;
      if (kind == kRlfPrintString) return std::string(strings[si] ? strings[si] : "");
      for (int k = 0; k < n; ++k) {
        if (k) text += ' ';
        if (kind == kRlfPrintInt) appendFormatted(text, "%d", ints[ii]);
        else appendFormatted(text, "%g", double(floats[fi + k]));
      }
      return text;
    };
    const bool numeric = conv == 'f' || conv == 'g' || conv == 'e' || conv == 'd' || conv == 'i' ||
                         conv == 'p' || conv == 'c' || conv == 'm';
    if (conv == 's') {
      appendFormatted(out, spec + 's', plain().c_str());
    } else if ((conv == 'd' || conv == 'i') && kind == kRlfPrintInt) {
      appendFormatted(out, spec + 'd', ints[ii]);
    } else if ((conv == 'd' || conv == 'i') && kind != kRlfPrintString) {
      // RSL has no int: `format("tex.%04d.tx", frame)` with a float frame is the idiom. Each
      // component goes toward zero, saturated, as a conversion to int would (3.7 printed "03.7").
      for (int k = 0; k < n; ++k) {
        const double v = double(floats[fi + k]);
        if (k) out += ' ';
        if (!std::isfinite(v)) {
          appendFormatted(out, "%g", v);
          continue;
        }
        const int whole = v >= 2147483647.0 ? INT32_MAX : v <= -2147483648.0 ? INT32_MIN : int(v);
        appendFormatted(out, spec + 'd', whole);
      }
    } else if (numeric && kind != kRlfPrintString) {
      // RSL's %p (point), %c (color) and %m (matrix) print every component as %f does.
      const char c = (conv == 'p' || conv == 'c' || conv == 'm') ? 'f' : conv;
      for (int k = 0; k < n; ++k) {
        const double v = kind == kRlfPrintInt ? double(ints[ii]) : double(floats[fi + k]);
        if (k) out += ' ';
        appendFormatted(out, spec + c, v);
      }
    } else if (numeric) {
      out += plain();  // a string for a number
    } else {
      out += spec + conv;  // not a conversion we know: as written
    }
    if (kind == kRlfPrintInt) ++ii;
    else if (kind == kRlfPrintString) ++si;
    else fi += n;
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
