// Shader bundles and the ELF relocatable-object loader (see shader_object.h).
#include "runtime/shader_object.h"

#include <elf.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <unordered_map>

#include "runtime/abi.h"
#include "runtime/symbols.h"

namespace relief::runtime {

void reflectDefaults(std::vector<ParamInfo>& params, uint32_t blockSize, void (*defaults)(void*)) {
  std::vector<uint64_t> block((size_t(blockSize) + 7) / 8 + 1, 0);
  defaults(block.data());
  const auto* bytes = reinterpret_cast<const unsigned char*>(block.data());
  for (ParamInfo& p : params) {
    p.defaultNumbers.clear(), p.defaultStrings.clear();
    const int elements = std::max(p.arrayLength, 1);
    if (p.type == ParamType::String) {
      for (int i = 0; i < elements; ++i) {
        const char* s = nullptr;
        std::memcpy(&s, bytes + p.offset + 8 * size_t(i), sizeof s);
        p.defaultStrings.push_back(s ? s : "");
      }
      continue;
    }
    const int n = paramComponents(p.type) * elements;
    for (int k = 0; k < n; ++k) {
      if (p.type == ParamType::Int) {
        int32_t v;
        std::memcpy(&v, bytes + p.offset + 4 * k, 4);
        p.defaultNumbers.push_back(double(v));
      } else {
        float v;
        std::memcpy(&v, bytes + p.offset + 4 * k, 4);
        p.defaultNumbers.push_back(v);
      }
    }
  }
}

namespace {

constexpr char kMagic[8] = {'R', 'L', 'F', 'B', 'N', 'D', 'L', '1'};
// Limits a well-formed bundle stays far below; a larger value is a malformed one.
constexpr uint32_t kMaxShaders = 4096, kMaxBlockBytes = 1u << 24;
constexpr uint64_t kMaxSectionBytes = uint64_t(1) << 28;

class Writer {
 public:
  void bytes(const void* p, size_t n) { out_.append(static_cast<const char*>(p), n); }
  void u8(uint8_t v) { bytes(&v, 1); }
  void u32(uint32_t v) { bytes(&v, 4); }
  void i32(int32_t v) { bytes(&v, 4); }
  void u64(uint64_t v) { bytes(&v, 8); }
  void str(std::string_view s) { u32(uint32_t(s.size())), bytes(s.data(), s.size()); }
  std::string take() { return std::move(out_); }

 private:
  std::string out_;
};

// Reads what Writer wrote; every read checks the bounds, so a truncated bundle is an error.
class Reader {
 public:
  explicit Reader(std::string_view in) : in_(in) {}
  bool ok() const { return ok_; }
  bool atEnd() const { return pos_ == in_.size(); }
  bool bytes(void* p, size_t n) {
    if (!ok_ || in_.size() - pos_ < n) return ok_ = false;
    std::memcpy(p, in_.data() + pos_, n);
    pos_ += n;
    return true;
  }
  uint8_t u8() { uint8_t v = 0; bytes(&v, 1); return v; }
  uint32_t u32() { uint32_t v = 0; bytes(&v, 4); return v; }
  int32_t i32() { int32_t v = 0; bytes(&v, 4); return v; }
  uint64_t u64() { uint64_t v = 0; bytes(&v, 8); return v; }
  std::string str() {
    const uint32_t n = u32();
    if (!ok_ || in_.size() - pos_ < n) return ok_ = false, std::string();
    std::string s(in_.substr(pos_, n));
    pos_ += n;
    return s;
  }
  std::string_view view(uint64_t n) {
    if (!ok_ || in_.size() - pos_ < n) return ok_ = false, std::string_view();
    std::string_view v = in_.substr(pos_, n);
    pos_ += n;
    return v;
  }

 private:
  std::string_view in_;
  size_t pos_ = 0;
  bool ok_ = true;
};

// One loaded object: its sections in one mapping, and its defined symbols by name.
class LoadedObject {
 public:
  ~LoadedObject() {
    if (base_) munmap(base_, size_);
  }
  bool load(std::string_view object, std::string* error);
  void* symbol(const std::string& name) const {
    auto it = symbols_.find(name);
    return it == symbols_.end() ? nullptr : it->second;
  }

 private:
  void* base_ = nullptr;
  size_t size_ = 0;
  std::unordered_map<std::string, void*> symbols_;
};

bool LoadedObject::load(std::string_view object, std::string* error) {
  auto fail = [&](const std::string& message) {
    *error = "shader object: " + message;
    return false;
  };
  const auto* data = reinterpret_cast<const unsigned char*>(object.data());
  const size_t size = object.size();
  Elf64_Ehdr eh;
  if (size < sizeof eh) return fail("truncated ELF header");
  std::memcpy(&eh, data, sizeof eh);
  if (std::memcmp(eh.e_ident, ELFMAG, SELFMAG) != 0 || eh.e_ident[EI_CLASS] != ELFCLASS64 ||
      eh.e_ident[EI_DATA] != ELFDATA2LSB || eh.e_type != ET_REL || eh.e_machine != EM_X86_64)
    return fail("not an x86-64 ELF relocatable object");
  if (eh.e_shentsize != sizeof(Elf64_Shdr) || eh.e_shoff > size ||
      (size - eh.e_shoff) / sizeof(Elf64_Shdr) < eh.e_shnum || eh.e_shstrndx >= eh.e_shnum)
    return fail("bad section header table");
  std::vector<Elf64_Shdr> sh(eh.e_shnum);
  std::memcpy(sh.data(), data + eh.e_shoff, sh.size() * sizeof(Elf64_Shdr));
  for (const Elf64_Shdr& s : sh) {
    if (s.sh_type != SHT_NOBITS && (s.sh_offset > size || s.sh_size > size - s.sh_offset))
      return fail("section outside the file");
    if (s.sh_size > kMaxSectionBytes) return fail("section too large");
  }
  if (sh[eh.e_shstrndx].sh_type != SHT_STRTAB) return fail("bad section name table");
  auto sectionName = [&](const Elf64_Shdr& s) -> std::string_view {
    const Elf64_Shdr& names = sh[eh.e_shstrndx];
    if (s.sh_name >= names.sh_size) return {};
    const char* p = reinterpret_cast<const char*>(data + names.sh_offset + s.sh_name);
    return std::string_view(p, strnlen(p, names.sh_size - s.sh_name));
  };

  // Sections to load, grouped by protection: code (with the stubs), read-only data, writable
  // data; each group starts on a page of its own. Unwind tables are not loaded: shader code
  // neither throws nor is thrown through.
  enum Group { kCode, kReadOnly, kWritable, kGroups };
  std::vector<int> group(sh.size(), -1);
  std::vector<size_t> offset(sh.size(), 0);
  for (size_t i = 0; i < sh.size(); ++i) {
    const Elf64_Shdr& s = sh[i];
    if (!(s.sh_flags & SHF_ALLOC) || s.sh_type == SHT_X86_64_UNWIND || sectionName(s) == ".eh_frame") continue;
    const std::string_view name = sectionName(s);
    if ((s.sh_type == SHT_INIT_ARRAY || s.sh_type == SHT_PREINIT_ARRAY || name.starts_with(".ctors") ||
         name.starts_with(".init_array")) && s.sh_size)
      return fail("static initialisers are not supported");
    if (s.sh_type != SHT_PROGBITS && s.sh_type != SHT_NOBITS) continue;
    if (s.sh_flags & SHF_TLS) return fail("thread-local data is not supported");
    group[i] = s.sh_flags & SHF_EXECINSTR ? kCode : s.sh_flags & SHF_WRITE ? kWritable : kReadOnly;
  }

  // Symbols.
  const Elf64_Shdr* symtab = nullptr;
  size_t symtabIndex = 0;
  for (size_t i = 0; i < sh.size(); ++i)
    if (sh[i].sh_type == SHT_SYMTAB) symtab = &sh[i], symtabIndex = i;
  if (!symtab || symtab->sh_entsize != sizeof(Elf64_Sym) || symtab->sh_link >= sh.size() ||
      sh[symtab->sh_link].sh_type != SHT_STRTAB)
    return fail("no symbol table");
  const size_t numSymbols = symtab->sh_size / sizeof(Elf64_Sym);
  std::vector<Elf64_Sym> syms(numSymbols);
  std::memcpy(syms.data(), data + symtab->sh_offset, numSymbols * sizeof(Elf64_Sym));
  const Elf64_Shdr& strtab = sh[symtab->sh_link];
  auto symbolName = [&](const Elf64_Sym& s) -> std::string {
    if (s.st_name >= strtab.sh_size) return {};
    const char* p = reinterpret_cast<const char*>(data + strtab.sh_offset + s.st_name);
    return std::string(p, strnlen(p, strtab.sh_size - s.st_name));
  };

  // Every symbol a call (PLT32) or a GOT load names gets a 16-byte stub in the code group:
  // `jmp *[rip]` followed by the 8-byte address, which doubles as the symbol's GOT entry. The
  // host's functions lie anywhere in the address space; the stubs are within reach of the code.
  std::vector<int64_t> stubOf(numSymbols, -1);
  size_t numStubs = 0;
  for (size_t i = 0; i < sh.size(); ++i) {
    const Elf64_Shdr& r = sh[i];
    if (r.sh_type == SHT_REL) return fail("REL relocations are not supported");
    if (r.sh_type != SHT_RELA) continue;
    if (r.sh_info >= sh.size()) return fail("relocations for no section");
    if (group[r.sh_info] < 0) continue;  // relocations of a section not loaded (unwind tables)
    if (r.sh_link != symtabIndex || r.sh_entsize != sizeof(Elf64_Rela)) return fail("bad relocation section");
    for (size_t k = 0; k < r.sh_size / sizeof(Elf64_Rela); ++k) {
      Elf64_Rela rel;
      std::memcpy(&rel, data + r.sh_offset + k * sizeof rel, sizeof rel);
      const uint32_t type = ELF64_R_TYPE(rel.r_info), sym = ELF64_R_SYM(rel.r_info);
      if (sym >= numSymbols) return fail("relocation names no symbol");
      if ((type == R_X86_64_PLT32 || type == R_X86_64_GOTPCREL || type == R_X86_64_GOTPCRELX ||
           type == R_X86_64_REX_GOTPCRELX) && stubOf[sym] < 0)
        stubOf[sym] = int64_t(numStubs++);
    }
  }

  // Layout.
  const size_t page = size_t(sysconf(_SC_PAGESIZE));
  size_t groupStart[kGroups], groupEnd[kGroups];
  size_t cursor = 0, stubsOffset = 0;
  for (int g = 0; g < kGroups; ++g) {
    cursor = (cursor + page - 1) / page * page;
    groupStart[g] = cursor;
    for (size_t i = 0; i < sh.size(); ++i) {
      if (group[i] != g) continue;
      const size_t align = std::max<size_t>(1, sh[i].sh_addralign);
      if (align & (align - 1) || align > page) return fail("unsupported section alignment");
      cursor = (cursor + align - 1) / align * align;
      offset[i] = cursor;
      cursor += sh[i].sh_size;
    }
    if (g == kCode) {
      cursor = (cursor + 15) / 16 * 16;
      stubsOffset = cursor;
      cursor += 16 * numStubs;
    }
    groupEnd[g] = cursor;
  }
  if (cursor > kMaxSectionBytes) return fail("sections too large");
  size_ = std::max<size_t>(page, (cursor + page - 1) / page * page);
  void* mem = mmap(nullptr, size_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (mem == MAP_FAILED) return fail("cannot map memory for the code");
  base_ = mem;
  auto* base = static_cast<unsigned char*>(mem);
  for (size_t i = 0; i < sh.size(); ++i)
    if (group[i] >= 0 && sh[i].sh_type != SHT_NOBITS) std::memcpy(base + offset[i], data + sh[i].sh_offset, sh[i].sh_size);

  // Symbol addresses.
  std::vector<uint64_t> address(numSymbols, 0);
  std::vector<uint8_t> known(numSymbols, 0);  // has an address relocations may use
  if (numSymbols) known[0] = 1;                 // the null symbol: 0
  for (size_t k = 1; k < numSymbols; ++k) {
    const Elf64_Sym& s = syms[k];
    const unsigned type = ELF64_ST_TYPE(s.st_info), bind = ELF64_ST_BIND(s.st_info);
    if (type == STT_FILE) continue;
    if (s.st_shndx == SHN_UNDEF) {
      const std::string name = symbolName(s);
      void* host = findRuntimeSymbol(name);
      if (!host && bind != STB_WEAK) return fail("calls '" + name + "', which shader code may not call");
      address[k] = reinterpret_cast<uint64_t>(host);
      known[k] = 1;
    } else if (s.st_shndx == SHN_ABS) {
      address[k] = s.st_value;
      known[k] = 1;
    } else if (s.st_shndx < sh.size() && s.st_shndx < SHN_LORESERVE && group[s.st_shndx] >= 0) {
      if (s.st_value > sh[s.st_shndx].sh_size) return fail("symbol outside its section");
      address[k] = reinterpret_cast<uint64_t>(base + offset[s.st_shndx]) + s.st_value;
      known[k] = 1;
      // Entry points: functions in the code, starting inside their section.
      if (type == STT_FUNC && bind != STB_LOCAL && group[s.st_shndx] == kCode && s.st_value < sh[s.st_shndx].sh_size)
        symbols_[symbolName(s)] = reinterpret_cast<void*>(address[k]);
    } else if (s.st_shndx == SHN_COMMON) {
      return fail("common symbols are not supported");
    }
  }
  for (size_t k = 0; k < numSymbols; ++k) {
    if (stubOf[k] < 0) continue;
    unsigned char* stub = base + stubsOffset + 16 * size_t(stubOf[k]);
    const unsigned char jmp[6] = {0xFF, 0x25, 0, 0, 0, 0};  // jmp *0(%rip): the address below
    std::memcpy(stub, jmp, 6);
    std::memcpy(stub + 6, &address[k], 8);
  }

  // Relocations.
  for (size_t i = 0; i < sh.size(); ++i) {
    const Elf64_Shdr& r = sh[i];
    if (r.sh_type != SHT_RELA || group[r.sh_info] < 0) continue;
    const Elf64_Shdr& target = sh[r.sh_info];
    for (size_t k = 0; k < r.sh_size / sizeof(Elf64_Rela); ++k) {
      Elf64_Rela rel;
      std::memcpy(&rel, data + r.sh_offset + k * sizeof rel, sizeof rel);
      const uint32_t type = ELF64_R_TYPE(rel.r_info), sym = ELF64_R_SYM(rel.r_info);
      if (sym >= numSymbols || !known[sym]) return fail("relocation against a symbol with no address");
      if (rel.r_offset > target.sh_size || target.sh_size - rel.r_offset < (type == R_X86_64_64 || type == R_X86_64_PC64 ? 8u : 4u))
        return fail("relocation outside its section");
      unsigned char* where = base + offset[r.sh_info] + rel.r_offset;
      const uint64_t P = reinterpret_cast<uint64_t>(where);
      const uint64_t S = address[sym];
      const int64_t A = rel.r_addend;
      const uint64_t stub = stubOf[sym] >= 0 ? reinterpret_cast<uint64_t>(base + stubsOffset + 16 * size_t(stubOf[sym])) : 0;
      auto put32 = [&](int64_t v, bool isSigned) {
        const bool fits = isSigned ? v >= std::numeric_limits<int32_t>::min() && v <= std::numeric_limits<int32_t>::max()
                                   : v >= 0 && v <= int64_t(std::numeric_limits<uint32_t>::max());
        if (!fits) return false;
        const uint32_t w = uint32_t(v);
        std::memcpy(where, &w, 4);
        return true;
      };
      bool ok = true;
      switch (type) {
        case R_X86_64_NONE: break;
        case R_X86_64_64: {
          const uint64_t v = S + uint64_t(A);
          std::memcpy(where, &v, 8);
          break;
        }
        case R_X86_64_PC64: {
          const uint64_t v = S + uint64_t(A) - P;
          std::memcpy(where, &v, 8);
          break;
        }
        case R_X86_64_PC32: ok = put32(int64_t(S + uint64_t(A) - P), true); break;
        case R_X86_64_PLT32: ok = put32(int64_t(stub + uint64_t(A) - P), true); break;
        case R_X86_64_GOTPCREL:
        case R_X86_64_GOTPCRELX:
        case R_X86_64_REX_GOTPCRELX: ok = put32(int64_t(stub + 6 + uint64_t(A) - P), true); break;
        case R_X86_64_32: ok = put32(int64_t(S + uint64_t(A)), false); break;
        case R_X86_64_32S: ok = put32(int64_t(S + uint64_t(A)), true); break;
        default: return fail("unsupported relocation type " + std::to_string(type));
      }
      if (!ok) return fail("relocation out of range (type " + std::to_string(type) + ")");
    }
  }

  // Seal: code read-only and executable, constants read-only.
  if (groupEnd[kCode] > groupStart[kCode] &&
      mprotect(base + groupStart[kCode], (groupEnd[kCode] - groupStart[kCode] + page - 1) / page * page,
               PROT_READ | PROT_EXEC) != 0)
    return fail("cannot make the code executable");
  if (groupEnd[kReadOnly] > groupStart[kReadOnly] &&
      mprotect(base + groupStart[kReadOnly], (groupEnd[kReadOnly] - groupStart[kReadOnly] + page - 1) / page * page,
               PROT_READ) != 0)
    return fail("cannot protect the constants");
  return true;
}

}  // namespace

std::string encodeShaderBundle(const std::vector<ShaderLayoutInfo>& shaders, std::string_view object) {
  Writer w;
  w.bytes(kMagic, sizeof kMagic);
  w.u32(kRlfAbiVersion);
  w.u32(uint32_t(shaders.size()));
  for (const ShaderLayoutInfo& s : shaders) {
    w.str(s.name), w.str(s.entrySymbol), w.str(s.defaultsSymbol);
    w.u32(s.blockSize), w.u8(s.ownNormal);
    w.u32(uint32_t(s.params.size()));
    for (const ParamInfo& p : s.params) {
      w.str(p.name), w.u8(uint8_t(p.type)), w.i32(p.arrayLength), w.u8(p.isOutput), w.u32(p.offset);
      w.i32(p.boundFlagOffset);
    }
  }
  w.u64(object.size());
  w.bytes(object.data(), object.size());
  return w.take();
}

bool loadShaderBundle(std::string_view bundle, std::vector<std::shared_ptr<const CompiledShader>>* shaders,
                      std::string* error) {
  Reader r(bundle);
  char magic[sizeof kMagic];
  if (!r.bytes(magic, sizeof magic) || std::memcmp(magic, kMagic, sizeof magic) != 0) {
    *error = "not a shader bundle of this version of relief";
    return false;
  }
  if (r.u32() != kRlfAbiVersion) {
    *error = "shader bundle made for another shader ABI (reliefc and relief of different versions)";
    return false;
  }
  const uint32_t numShaders = r.u32();
  if (!r.ok() || numShaders > kMaxShaders) {
    *error = "shader bundle: bad shader count";
    return false;
  }
  std::vector<ShaderLayoutInfo> layouts(numShaders);
  for (ShaderLayoutInfo& s : layouts) {
    s.name = r.str(), s.entrySymbol = r.str(), s.defaultsSymbol = r.str();
    s.blockSize = r.u32(), s.ownNormal = r.u8() != 0;
    if (s.blockSize > kMaxBlockBytes) {
      *error = "shader bundle: parameter block too large";
      return false;
    }
    const uint32_t numParams = r.u32();
    for (uint32_t k = 0; k < numParams && r.ok(); ++k) {
      ParamInfo p;
      p.name = r.str();
      const uint8_t type = r.u8();
      if (type > uint8_t(ParamType::Matrix)) {
        *error = "shader bundle: bad parameter type";
        return false;
      }
      p.type = ParamType(type);
      p.arrayLength = r.i32(), p.isOutput = r.u8() != 0, p.offset = r.u32(), p.boundFlagOffset = r.i32();
      const uint64_t bytes = uint64_t(std::max(p.arrayLength, 1)) * (p.type == ParamType::String ? 8 : 4 * paramComponents(p.type));
      if (p.arrayLength < 0 || p.offset + bytes > s.blockSize ||
          (p.boundFlagOffset != -1 && (p.boundFlagOffset < 0 || int64_t(p.boundFlagOffset) + 4 > int64_t(s.blockSize)))) {
        *error = "shader bundle: parameter '" + p.name + "' outside its block";
        return false;
      }
      s.params.push_back(std::move(p));
    }
  }
  const std::string_view object = r.view(r.u64());
  if (!r.ok() || !r.atEnd()) {
    *error = "shader bundle: truncated";
    return false;
  }
  auto loaded = std::make_shared<LoadedObject>();
  if (!loaded->load(object, error)) return false;
  for (ShaderLayoutInfo& s : layouts) {
    void* entry = loaded->symbol(s.entrySymbol);
    void* defaults = loaded->symbol(s.defaultsSymbol);
    if (!entry || !defaults) {
      *error = "shader object: no symbol '" + (entry ? s.defaultsSymbol : s.entrySymbol) + "'";
      return false;
    }
    reflectDefaults(s.params, s.blockSize, reinterpret_cast<void (*)(void*)>(defaults));
    shaders->push_back(std::make_shared<CompiledShader>(s.name, reinterpret_cast<RlfShaderEntry>(entry),
                                                        std::move(s.params), s.blockSize, loaded, s.ownNormal));
  }
  return true;
}

}  // namespace relief::runtime
