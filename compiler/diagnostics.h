// The diagnostics engine: call sites report an ID, a location, ranges and arguments; consumers
// (text, JSON) render them sorted by location. Shared by every compiler stage; no LLVM here.
#pragma once

#include <algorithm>
#include <cstdint>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "compiler/json_text.h"
#include "compiler/source_manager.h"

namespace relief::compiler {

enum class DiagId : uint16_t {
#define DIAG(Id, Severity, Flag, Format) Id,
#include "compiler/diagnostic_kinds.def"
};

enum class Severity : uint8_t { Note, Warning, Error, Fatal };

struct Diagnostic {
  DiagId id;
  Severity severity;
  SourceLoc loc;
  std::vector<SourceRange> ranges;
  std::string message;      // formatted
  std::string flag;         // warning flag name without -W, or empty
  std::vector<Diagnostic> notes;
  std::string file;         // for diagnostics without a location: the file they concern
  uint32_t order = 0;       // emission order: ties in location keep it
};

struct DiagnosticOptions {
  bool warningsAsErrors = false;
  bool noWarnings = false;
  unsigned errorLimit = 20;  // 0: unlimited
  std::vector<std::string> disabledWarnings;  // -Wno-<name>
  std::vector<std::string> errorWarnings;     // -Werror=<name>: this warning is an error
  std::vector<std::string> notErrorWarnings;  // -Wno-error=<name>: a warning even under -Werror
};


// The -W names of all warnings, for validating command-line flags.
std::vector<std::string> warningFlags();

class DiagnosticsEngine {
 public:
  explicit DiagnosticsEngine(DiagnosticOptions options = {}) : options_(options) {}

  // Builder returned by report(): add ranges and arguments, then it is recorded on destruction.
  class Builder {
   public:
    Builder(DiagnosticsEngine* engine, DiagId id, SourceLoc loc);
    Builder(Builder&& other) noexcept;
    Builder(const Builder&) = delete;
    ~Builder();
    Builder& arg(std::string_view text) {
      args_.emplace_back(text);
      return *this;
    }
    Builder& arg(long long n) {
      args_.push_back(std::to_string(n));
      return *this;
    }
    Builder& range(SourceRange r) {
      if (r.isValid()) ranges_.push_back(r);
      return *this;
    }
    // Names the file of a diagnostic that has no location ("<file>: error: ...").
    Builder& inFile(std::string_view file) {
      file_ = file;
      return *this;
    }
    // Attaches a note to this diagnostic (printed right after it).
    Builder& note(DiagId id, SourceLoc loc, std::vector<std::string> args = {}, SourceRange r = {});

   private:
    DiagnosticsEngine* engine_;
    DiagId id_;
    SourceLoc loc_;
    std::vector<std::string> args_;
    std::vector<SourceRange> ranges_;
    std::vector<Diagnostic> notes_;
    std::string file_;
  };

  Builder report(DiagId id, SourceLoc loc) { return Builder(this, id, loc); }

  bool hasErrors() const { return numErrors_ > 0 || limitReached_; }
  // Errors other than warnings promoted by -Werror: the code may be incomplete or mistyped, so
  // analyses that need a whole, well-typed program (unused, uninitialized) stand down. Promoted
  // warnings leave the program whole, and the user should see every warning at once.
  bool hasHardErrors() const { return numErrors_ > numPromoted_ || limitReached_; }
  unsigned numErrors() const { return numErrors_; }
  unsigned numHardErrors() const { return numErrors_ - numPromoted_; }
  // The errors sorted() shows: at most the error limit.
  unsigned numShownErrors() const {
    return limitReached_ ? std::min(numErrors_, options_.errorLimit) : numErrors_;
  }
  // The file a diagnostic without a position (the error-limit notice) names.
  void setFileName(std::string name) { fileName_ = std::move(name); }
  unsigned numWarnings() const { return numWarnings_; }
  // The warnings sorted(sm) shows: past the error limit, only those before the cut.
  unsigned numShownWarnings(const SourceManager& sm) const;
  // Diagnostics sorted by location (then emission order); with a SourceManager, an included
  // file's diagnostics sort at its #include.
  std::vector<Diagnostic> sorted() const;
  std::vector<Diagnostic> sorted(const SourceManager& sm) const;
  const std::vector<Diagnostic>& diagnostics() const { return diags_; }

  static const char* formatOf(DiagId id);
  static Severity defaultSeverity(DiagId id);
  static std::string format(DiagId id, const std::vector<std::string>& args);

 private:
  void record(Diagnostic d);

  DiagnosticOptions options_;
  std::vector<Diagnostic> diags_;
  static constexpr size_t kMaxKept = 100000;
  // sorted()'s tail: the first errorLimit errors in source order, then the limit's notice.
  std::vector<Diagnostic> limited(std::vector<Diagnostic> in) const;
  std::string fileName_;
  unsigned numErrors_ = 0;
  unsigned numPromoted_ = 0;  // of numErrors_: warnings made errors by -Werror
  unsigned numWarnings_ = 0;
  bool limitReached_ = false;
};

// Clang-style text rendering: header, source line, caret line with `~` ranges, notes.
struct TextDiagnosticOptions {
  bool color = false;
};
void renderText(std::ostream& out, const SourceManager& sm, const Diagnostic& d,
                const TextDiagnosticOptions& options = {});
void renderAllText(std::ostream& out, const SourceManager& sm, const DiagnosticsEngine& engine,
                   const TextDiagnosticOptions& options = {});
// "1 warning and 2 errors generated." or empty when there is nothing to summarize.
std::string summaryLine(unsigned numWarnings, unsigned numErrors);
// One JSON object per line per diagnostic (notes nested in "notes").
void renderJson(std::ostream& out, const SourceManager& sm, const Diagnostic& d);

}  // namespace relief::compiler
