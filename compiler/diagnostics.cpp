// Diagnostics engine and its text/JSON consumers (see diagnostics.h).
#include "compiler/diagnostics.h"

#include <algorithm>
#include <cstdio>

#include "compiler/utf8.h"

namespace relief::compiler {

namespace {
struct DiagInfo {
  Severity severity;
  const char* flag;
  const char* format;
};
constexpr DiagInfo kDiagInfos[] = {
#define DIAG(Id, Sev, Flag, Format) {Severity::Sev, Flag, Format},
#include "compiler/diagnostic_kinds.def"
};
}  // namespace

std::vector<std::string> warningFlags() {
  std::vector<std::string> out;
  for (const DiagInfo& info : kDiagInfos)
    if (*info.flag && std::find(out.begin(), out.end(), info.flag) == out.end()) out.push_back(info.flag);
  return out;
}

const char* DiagnosticsEngine::formatOf(DiagId id) { return kDiagInfos[size_t(id)].format; }
Severity DiagnosticsEngine::defaultSeverity(DiagId id) { return kDiagInfos[size_t(id)].severity; }

std::string DiagnosticsEngine::format(DiagId id, const std::vector<std::string>& args) {
  std::string out;
  for (const char* p = formatOf(id); *p; ++p) {
    if (*p == '%' && p[1] >= '0' && p[1] <= '9') {
      const size_t i = size_t(p[1] - '0');
      if (i < args.size()) out += args[i];
      ++p;
    } else if (*p == '%' && p[1] == 's' && p[2] >= '0' && p[2] <= '9') {
      // clang's %sN: an English plural 's' unless argument N is 1 ("1 argument", "2 arguments").
      const size_t i = size_t(p[2] - '0');
      if (i < args.size() && args[i] != "1") out += 's';
      p += 2;
    } else {
      out += *p;
    }
  }
  return out;
}

DiagnosticsEngine::Builder::Builder(DiagnosticsEngine* engine, DiagId id, SourceLoc loc)
    : engine_(engine), id_(id), loc_(loc) {}

DiagnosticsEngine::Builder::Builder(Builder&& other) noexcept
    : engine_(other.engine_),
      id_(other.id_),
      loc_(other.loc_),
      args_(std::move(other.args_)),
      ranges_(std::move(other.ranges_)),
      notes_(std::move(other.notes_)),
      file_(std::move(other.file_)) {
  other.engine_ = nullptr;
}

DiagnosticsEngine::Builder& DiagnosticsEngine::Builder::note(DiagId id, SourceLoc loc,
                                                              std::vector<std::string> args,
                                                              SourceRange r) {
  Diagnostic n;
  n.id = id;
  n.severity = Severity::Note;
  n.loc = loc;
  if (r.isValid()) n.ranges.push_back(r);
  n.message = format(id, args);
  notes_.push_back(std::move(n));
  return *this;
}

DiagnosticsEngine::Builder::~Builder() {
  if (!engine_) return;
  Diagnostic d;
  d.id = id_;
  d.severity = defaultSeverity(id_);
  d.loc = loc_;
  d.ranges = std::move(ranges_);
  d.message = format(id_, args_);
  d.flag = kDiagInfos[size_t(id_)].flag;
  d.notes = std::move(notes_);
  d.file = std::move(file_);
  engine_->record(std::move(d));
}

void DiagnosticsEngine::record(Diagnostic d) {
  bool promoted = false;
  if (d.severity == Severity::Warning) {
    if (options_.noWarnings) return;
    for (const std::string& off : options_.disabledWarnings)
      if (off == d.flag) return;
    auto listed = [&](const std::vector<std::string>& names) {
      return std::find(names.begin(), names.end(), d.flag) != names.end();
    };
    promoted = (options_.warningsAsErrors && !listed(options_.notErrorWarnings)) || listed(options_.errorWarnings);
    if (promoted) d.severity = Severity::Error;
  }
  if (d.severity >= Severity::Error) {
    ++numErrors_;
    numPromoted_ += promoted;
    // The limit applies to the errors shown, taken in source order (sorted()): parse errors are
    // found before type errors earlier in the file, which must not be the ones dropped.
    if (options_.errorLimit && numErrors_ > options_.errorLimit) limitReached_ = true;
  } else if (d.severity == Severity::Warning) {
    ++numWarnings_;
  }
  if (diags_.size() >= kMaxKept) return;  // hostile input: what is kept is plenty to sort from
  d.order = uint32_t(diags_.size());
  diags_.push_back(std::move(d));
}

unsigned DiagnosticsEngine::numShownWarnings(const SourceManager& sm) const {
  if (!limitReached_) return numWarnings_;
  unsigned n = 0;
  for (const Diagnostic& d : sorted(sm)) n += d.severity == Severity::Warning;
  return n;
}

std::vector<Diagnostic> DiagnosticsEngine::limited(std::vector<Diagnostic> in) const {
  if (!limitReached_) return in;
  std::vector<Diagnostic> out;
  unsigned errors = 0;
  for (Diagnostic& d : in) {
    if (d.severity >= Severity::Error && ++errors > options_.errorLimit) break;
    out.push_back(std::move(d));
  }
  Diagnostic fatal;
  fatal.id = DiagId::FatalTooManyErrors;
  fatal.severity = Severity::Fatal;
  fatal.message = format(fatal.id, {});
  fatal.file = fileName_;
  fatal.order = uint32_t(diags_.size());
  out.push_back(std::move(fatal));
  return out;
}

std::vector<Diagnostic> DiagnosticsEngine::sorted() const {
  std::vector<Diagnostic> out = diags_;
  auto key = [](const Diagnostic& d) {
    // The error-limit notice closes the list wherever it was raised.
    return d.id == DiagId::FatalTooManyErrors ? UINT32_MAX : d.loc.offset;
  };
  std::stable_sort(out.begin(), out.end(), [&](const Diagnostic& a, const Diagnostic& b) {
    return key(a) < key(b);
  });
  return limited(std::move(out));
}

std::vector<Diagnostic> DiagnosticsEngine::sorted(const SourceManager& sm) const {
  std::vector<std::pair<std::vector<uint32_t>, const Diagnostic*>> keyed;
  for (const Diagnostic& d : diags_)
    keyed.emplace_back(d.id == DiagId::FatalTooManyErrors ? std::vector<uint32_t>{UINT32_MAX} : sm.sortKey(d.loc), &d);
  std::stable_sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Diagnostic> out;
  for (const auto& k : keyed) out.push_back(*k.second);
  return limited(std::move(out));
}

namespace {
const char* severityName(Severity s) {
  switch (s) {
    case Severity::Note: return "note";
    case Severity::Warning: return "warning";
    case Severity::Error: return "error";
    case Severity::Fatal: return "fatal error";
  }
  return "error";
}
const char* severityColor(Severity s) {
  switch (s) {
    case Severity::Note: return "\033[1;30m";
    case Severity::Warning: return "\033[1;35m";
    default: return "\033[1;31m";
  }
}
constexpr const char* kBold = "\033[1m";
constexpr const char* kGreen = "\033[1;32m";
constexpr const char* kReset = "\033[0m";

// `lastInclude` (may be null) is where the file of the previous diagnostic or note was included:
// like clang, the stack is not repeated for consecutive diagnostics in the same included file.
void renderOne(std::ostream& out, const SourceManager& sm, const Diagnostic& d,
               const TextDiagnosticOptions& opt, SourceLoc* lastInclude) {
  const PresumedLoc p = sm.presumed(d.loc);
  bool repeated = false;
  if (lastInclude && p.isValid()) {
    const SourceLoc include = sm.includedFrom(sm.fileOf(d.loc));
    repeated = include == *lastInclude;
    *lastInclude = include;
  }
  if (p.isValid() && d.severity != Severity::Note && !repeated) {
    // The include stack as clang prints it: outermost #include first, one line each.
    std::vector<SourceLoc> stack;
    for (SourceLoc at = sm.includedFrom(sm.fileOf(d.loc)); at.isValid() && stack.size() < 100;
         at = sm.includedFrom(sm.fileOf(at)))
      stack.push_back(at);
    for (auto it = stack.rbegin(); it != stack.rend(); ++it) {
      const PresumedLoc ip = sm.presumed(*it);
      out << "In file included from " << ip.file << ':' << ip.line << ":\n";
    }
  }
  if (opt.color) out << kBold;
  if (p.isValid())
    out << p.file << ':' << p.line << ':' << p.column << ": ";
  else if (!d.file.empty())
    out << d.file << ": ";
  if (opt.color) out << severityColor(d.severity);
  out << severityName(d.severity) << ": ";
  if (opt.color) out << kReset << kBold;
  out << d.message;
  if (!d.flag.empty() && d.severity != Severity::Note) {
    out << " [-W";
    if (d.severity == Severity::Error) out << "error,-W";
    out << d.flag << ']';
  }
  if (opt.color) out << kReset;
  out << '\n';
  if (!p.isValid()) return;

  const std::string_view fullLine = sm.lineText(d.loc);
  // Column arithmetic in bytes of this line; ranges on other lines are not drawn.
  const uint32_t lineStart = d.loc.offset - (p.column - 1);
  const uint32_t lineEnd = lineStart + uint32_t(fullLine.size());
  std::string caret(fullLine.size() + 1, ' ');
  for (const SourceRange& r : d.ranges) {
    uint32_t b = std::max(r.begin.offset, lineStart);
    uint32_t e = std::min(r.end.offset, lineEnd);
    if (sm.fileOf(r.begin) != sm.fileOf(d.loc)) continue;
    for (uint32_t o = b; o < e; ++o) caret[o - lineStart] = '~';
  }
  const bool caretInRange = caret[p.column - 1] == '~';
  caret[p.column - 1] = '^';
  // A very long line (generated code, a file of one line) is shown as a window around the caret,
  // as clang does: 10,000 diagnostics on a 180 KB line printed 3 GB.
  constexpr size_t kLongLine = 256, kWindowBefore = 100, kWindowBytes = 200;
  std::string_view line = fullLine;
  bool cutBefore = false, cutAfter = false;
  if (fullLine.size() > kLongLine) {
    size_t from = p.column - 1 > kWindowBefore ? p.column - 1 - kWindowBefore : 0;
    while (from > 0 && (static_cast<unsigned char>(fullLine[from]) & 0xC0) == 0x80) --from;  // whole characters
    size_t to = std::min(fullLine.size(), from + kWindowBytes);
    while (to < fullLine.size() && (static_cast<unsigned char>(fullLine[to]) & 0xC0) == 0x80) ++to;
    cutBefore = from > 0, cutAfter = to < fullLine.size();
    line = fullLine.substr(from, to - from);
    caret = caret.substr(from, to - from + 1);
  }
  // One caret column per character, not per byte: a UTF-8 continuation byte adds no column (what
  // it carries moves onto its character's lead byte), so the caret stays under its token after a
  // 'ü' in a comment or string.
  // Only the continuation bytes of valid sequences: a stray byte (Latin-1 text) shows as one cell.
  std::vector<bool> continuation(line.size(), false);
  for (size_t i = 0; i < line.size();) {
    uint32_t code = 0;
    const int length = utf8Sequence(line.data() + i, line.data() + line.size(), &code);
    for (int k = 1; k < length; ++k) continuation[i + size_t(k)] = true;
    i += size_t(std::max(length, 1));
  }
  // Tabs are shown expanded to stops of 8 columns, as clang does, in the line and under it alike:
  // a terminal's own tab stops would not advance the underline's '~' with them (it fell short).
  constexpr size_t kTabStop = 8;
  std::string shown, columns;
  size_t column = cutBefore ? 3 : 0;  // after the "..."
  for (size_t i = 0; i < caret.size(); ++i) {
    if (i < line.size() && continuation[i] && !columns.empty()) {
      shown.push_back(line[i]);
      if (caret[i] != ' ' && columns.back() == ' ') columns.back() = caret[i];
      continue;
    }
    if (i < line.size() && line[i] == '\t') {
      const size_t width = kTabStop - column % kTabStop;
      shown.append(width, ' ');
      columns.push_back(caret[i]);
      columns.append(width - 1, caret[i] == '^' ? (caretInRange ? '~' : ' ') : caret[i]);
      column += width;
      continue;
    }
    if (i < line.size()) shown.push_back(line[i]);
    columns.push_back(caret[i]);
    ++column;
  }
  out << (cutBefore ? "..." : "") << shown << (cutAfter ? "..." : "") << '\n';
  caret = std::move(columns);
  if (cutBefore) caret.insert(0, "   ");  // under the "..."
  while (!caret.empty() && caret.back() == ' ') caret.pop_back();
  if (opt.color) out << kGreen;
  out << caret;
  if (opt.color) out << kReset;
  out << '\n';
}

void jsonString(std::ostream& out, std::string_view s) { out << jsonQuoted(s); }

void jsonBody(std::ostream& out, const SourceManager& sm, const Diagnostic& d) {
  const PresumedLoc p = sm.presumed(d.loc);
  out << "{\"severity\":\"" << severityName(d.severity) << "\"";
  if (p.isValid()) {
    out << ",\"file\":";
    jsonString(out, p.file);
    out << ",\"line\":" << p.line << ",\"column\":" << p.column;
  } else if (!d.file.empty()) {
    out << ",\"file\":";
    jsonString(out, d.file);
  }
  // The include stack, outermost #include first, as the text's "In file included from" lines.
  if (p.isValid() && sm.includedFrom(sm.fileOf(d.loc)).isValid()) {
    std::vector<SourceLoc> stack;
    for (SourceLoc at = sm.includedFrom(sm.fileOf(d.loc)); at.isValid() && stack.size() < 100;
         at = sm.includedFrom(sm.fileOf(at)))
      stack.push_back(at);
    out << ",\"included_from\":[";
    for (auto it = stack.rbegin(); it != stack.rend(); ++it) {
      const PresumedLoc ip = sm.presumed(*it);
      out << (it == stack.rbegin() ? "" : ",") << "{\"file\":";
      jsonString(out, ip.file);
      out << ",\"line\":" << ip.line << '}';
    }
    out << ']';
  }
  out << ",\"message\":";
  jsonString(out, d.message);
  if (!d.flag.empty()) out << ",\"flag\":\"-W" << d.flag << "\"";
  if (!d.ranges.empty()) {
    out << ",\"ranges\":[";
    for (size_t i = 0; i < d.ranges.size(); ++i) {
      const PresumedLoc b = sm.presumed(d.ranges[i].begin);
      const PresumedLoc e = sm.presumed(d.ranges[i].end);
      out << (i ? "," : "") << "{\"begin\":[" << b.line << ',' << b.column << "],\"end\":["
          << e.line << ',' << e.column << "]}";
    }
    out << ']';
  }
  if (!d.notes.empty()) {
    out << ",\"notes\":[";
    for (size_t i = 0; i < d.notes.size(); ++i) {
      if (i) out << ',';
      jsonBody(out, sm, d.notes[i]);
    }
    out << ']';
  }
  out << '}';
}
}  // namespace

namespace {
void renderWithNotes(std::ostream& out, const SourceManager& sm, const Diagnostic& d,
                     const TextDiagnosticOptions& options, SourceLoc* lastInclude) {
  renderOne(out, sm, d, options, lastInclude);
  for (const Diagnostic& n : d.notes) renderOne(out, sm, n, options, lastInclude);
}
}  // namespace

void renderText(std::ostream& out, const SourceManager& sm, const Diagnostic& d,
                const TextDiagnosticOptions& options) {
  renderWithNotes(out, sm, d, options, nullptr);
}

void renderAllText(std::ostream& out, const SourceManager& sm, const DiagnosticsEngine& engine,
                   const TextDiagnosticOptions& options) {
  SourceLoc lastInclude;
  for (const Diagnostic& d : engine.sorted(sm)) renderWithNotes(out, sm, d, options, &lastInclude);
}

std::string summaryLine(unsigned numWarnings, unsigned numErrors) {
  auto plural = [](unsigned n, const char* word) {
    return std::to_string(n) + " " + word + (n == 1 ? "" : "s");
  };
  if (numWarnings && numErrors)
    return plural(numWarnings, "warning") + " and " + plural(numErrors, "error") + " generated.";
  if (numWarnings) return plural(numWarnings, "warning") + " generated.";
  if (numErrors) return plural(numErrors, "error") + " generated.";
  return {};
}

void renderJson(std::ostream& out, const SourceManager& sm, const Diagnostic& d) {
  jsonBody(out, sm, d);
  out << '\n';
}

}  // namespace relief::compiler
