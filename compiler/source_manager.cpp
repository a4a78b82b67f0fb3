// Buffer ownership and lazy line tables for SourceLoc → file:line:col (see source_manager.h).
#include "compiler/source_manager.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace relief::compiler {

SourceManager::FileId SourceManager::addBuffer(std::string name, std::string text, SourceLoc includedFrom) {
  auto f = std::make_unique<File>();
  f->name = std::move(name);
  f->includedFrom = includedFrom;
  f->text = std::move(text);
  f->base = next_;
  // One extra offset for the end-of-file position, one more as a gap so buffers never touch.
  next_ += uint32_t(f->text.size()) + 2;
  files_.push_back(std::move(f));
  return FileId(files_.size() - 1);
}

bool SourceManager::addFile(const std::string& path, FileId* id, std::string* error, SourceLoc includedFrom) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    *error = "cannot open file: it is a directory";
    return false;
  }
  // A device or a pipe (/dev/zero) would be read for ever; a source file is a regular file, and
  // one larger than any shader could be is a mistake, not something to read into memory.
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (!ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status)) {
    *error = "cannot open file: not a regular file";
    return false;
  }
  if (const uintmax_t size = std::filesystem::file_size(path, ec); !ec && size > kMaxSourceBytes) {
    *error = "cannot open file: it is larger than " + std::to_string(kMaxSourceBytes >> 20) + " MiB";
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *error = std::string("cannot open file: ") + std::strerror(errno);
    return false;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) {
    *error = "cannot read file";
    return false;
  }
  *id = addBuffer(path, ss.str(), includedFrom);
  return true;
}

std::vector<uint32_t> SourceManager::sortKey(SourceLoc loc) const {
  std::vector<uint32_t> key{loc.offset};
  if (!loc.isValid() || files_.empty()) return key;
  for (SourceLoc at = includedFrom(fileOf(loc)); at.isValid() && key.size() < 100; at = includedFrom(fileOf(at)))
    key.insert(key.begin(), at.offset);
  return key;
}

SourceManager::FileId SourceManager::fileOf(SourceLoc loc) const {
  auto it = std::upper_bound(files_.begin(), files_.end(), loc.offset,
                             [](uint32_t off, const std::unique_ptr<File>& f) { return off < f->base; });
  return FileId(it == files_.begin() ? 0 : (it - files_.begin()) - 1);
}

void SourceManager::computeLines(const File& f) const {
  if (!f.lineStarts.empty()) return;
  f.lineStarts.push_back(0);
  const std::string& t = f.text;
  for (uint32_t i = 0; i < t.size(); ++i) {
    if (t[i] == '\n') {
      f.lineStarts.push_back(i + 1);
    } else if (t[i] == '\r') {
      if (i + 1 < t.size() && t[i + 1] == '\n') ++i;
      f.lineStarts.push_back(i + 1);
    }
  }
}

void SourceManager::computeSplices(const File& f) const {
  if (f.splicedReady) return;
  f.splicedReady = true;
  const std::string& t = f.text;
  if (t.find('\\') == std::string::npos) return;
  std::string out;
  out.reserve(t.size());
  uint32_t removedSoFar = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    if (t[i] == '\\' && i + 1 < t.size() && (t[i + 1] == '\n' || t[i + 1] == '\r')) {
      const size_t n = t[i + 1] == '\r' && i + 2 < t.size() && t[i + 2] == '\n' ? 3 : 2;
      removedSoFar += uint32_t(n);
      f.spliceAt.push_back(uint32_t(out.size()));
      f.removed.push_back(removedSoFar);
      i += n - 1;
      continue;
    }
    out += t[i];
  }
  if (!f.spliceAt.empty()) f.spliced = std::move(out);
}

std::string_view SourceManager::splicedText(FileId id) const {
  const File& f = *files_[id];
  computeSplices(f);
  return f.spliceAt.empty() ? std::string_view(f.text) : std::string_view(f.spliced);
}

uint32_t SourceManager::physicalOffset(FileId id, uint32_t splicedOffset) const {
  const File& f = *files_[id];
  computeSplices(f);
  // A character right after a splice sits after the removed bytes.
  auto it = std::upper_bound(f.spliceAt.begin(), f.spliceAt.end(), splicedOffset);
  return it == f.spliceAt.begin() ? splicedOffset : splicedOffset + f.removed[size_t(it - f.spliceAt.begin()) - 1];
}

PresumedLoc SourceManager::presumed(SourceLoc loc) const {
  if (!loc.isValid() || files_.empty()) return {};
  const File& f = file(loc);
  computeLines(f);
  const uint32_t off = std::min<uint32_t>(loc.offset - f.base, uint32_t(f.text.size()));
  auto it = std::upper_bound(f.lineStarts.begin(), f.lineStarts.end(), off);
  const uint32_t line = uint32_t(it - f.lineStarts.begin());
  return {f.name, line, off - f.lineStarts[line - 1] + 1};
}

std::string_view SourceManager::lineText(SourceLoc loc) const {
  if (!loc.isValid() || files_.empty()) return {};
  const File& f = file(loc);
  const PresumedLoc p = presumed(loc);
  const uint32_t start = f.lineStarts[p.line - 1];
  uint32_t end = start;
  while (end < f.text.size() && f.text[end] != '\n' && f.text[end] != '\r') ++end;
  return std::string_view(f.text).substr(start, end - start);
}

const char* SourceManager::character(SourceLoc loc) const {
  const File& f = file(loc);
  return f.text.c_str() + std::min<size_t>(loc.offset - f.base, f.text.size());
}

}  // namespace relief::compiler
