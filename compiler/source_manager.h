// Owns every source buffer of a compilation and maps 32-bit SourceLocs to file, line and column.
// Used by the lexer (to create locations) and by diagnostics (to render them); no LLVM here.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace relief::compiler {

// An offset into the concatenation of all buffers; 0 is "no location". Cheap to copy and compare,
// and ordered by (buffer, offset), which is the order diagnostics are printed in.
struct SourceLoc {
  uint32_t offset = 0;
  bool isValid() const { return offset != 0; }
  SourceLoc advanced(uint32_t n) const { return {offset + n}; }
  friend bool operator==(SourceLoc a, SourceLoc b) = default;
  friend auto operator<=>(SourceLoc a, SourceLoc b) = default;
};

// Half-open [begin, end).
struct SourceRange {
  SourceLoc begin;
  SourceLoc end;
  bool isValid() const { return begin.isValid(); }
};

struct PresumedLoc {
  std::string_view file;
  uint32_t line = 0;    // 1-based
  uint32_t column = 0;  // 1-based byte offset in the line (a tab counts 1)
  bool isValid() const { return line != 0; }
};

class SourceManager {
 public:
  using FileId = uint32_t;
  // The largest source file read (addFile): 64 MiB, far beyond any shader.
  static constexpr uintmax_t kMaxSourceBytes = uintmax_t(64) << 20;

  // Adds a buffer named `name` (what diagnostics print) and returns its id.
  FileId addBuffer(std::string name, std::string text, SourceLoc includedFrom = {});
  // Reads a file from disk; returns false and sets *error on failure (the reason, not the path).
  bool addFile(const std::string& path, FileId* id, std::string* error, SourceLoc includedFrom = {});
  // Where the file was #included (invalid for main files and scratch buffers).
  SourceLoc includedFrom(FileId id) const { return files_[id]->includedFrom; }
  // Offsets from the outermost #include down to `loc`: diagnostics sort by this, so an included
  // file sorts at its #include.
  std::vector<uint32_t> sortKey(SourceLoc loc) const;

  std::string_view text(FileId id) const { return files_[id]->text; }
  // The text the lexer reads: text(id) with every backslash-newline removed (C's phase 2, §1.1).
  // `physicalOffset` maps an offset in it back into text(id), so locations stay those of the file.
  std::string_view splicedText(FileId id) const;
  uint32_t physicalOffset(FileId id, uint32_t splicedOffset) const;
  const std::string& name(FileId id) const { return files_[id]->name; }
  SourceLoc startOf(FileId id) const { return {files_[id]->base}; }
  FileId fileOf(SourceLoc loc) const;

  PresumedLoc presumed(SourceLoc loc) const;
  // The full text of the line holding `loc`, without its terminator.
  std::string_view lineText(SourceLoc loc) const;
  // Pointer to the character at `loc` (the buffers are NUL-terminated).
  const char* character(SourceLoc loc) const;

 private:
  struct File {
    std::string name;
    std::string text;
    uint32_t base = 0;                      // SourceLoc offset of text[0]
    SourceLoc includedFrom;
    mutable std::vector<uint32_t> lineStarts;  // filled on first query
    // Splicing, done on first query; `spliced` stays empty when the text has no backslash-newline.
    mutable bool splicedReady = false;
    mutable std::string spliced;
    mutable std::vector<uint32_t> spliceAt;  // spliced offset of each removal, ascending
    mutable std::vector<uint32_t> removed;   // bytes removed up to and including that removal
  };
  void computeSplices(const File& f) const;
  const File& file(SourceLoc loc) const { return *files_[fileOf(loc)]; }
  void computeLines(const File& f) const;

  std::vector<std::unique_ptr<File>> files_;
  uint32_t next_ = 1;  // 0 stays invalid
};

}  // namespace relief::compiler
