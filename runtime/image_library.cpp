// Finds and loads the image-library plugin (see image_library.h). Loading happens at most once;
// a failure is remembered, so a scene with a missing plugin reports the same reason everywhere.
#include "runtime/image_library.h"

#include <dlfcn.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <system_error>
#include <vector>

namespace relief::runtime {
namespace {

namespace fs = std::filesystem;

struct Loaded {
  const RlfImageLibrary* table = nullptr;
  std::string why;
};
std::atomic<bool> loadedFlag{false};

std::vector<std::string> candidates() {
  // Absolute: dlopen would look a bare name up on the library path, not in the working directory.
  if (const char* env = std::getenv("RELIEF_IMAGE_LIBRARY"); env && *env) {
    std::error_code ec;
    const fs::path absolute = fs::absolute(env, ec);
    return {ec ? std::string(env) : absolute.string()};
  }
  std::vector<std::string> paths;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) paths.push_back((exe.parent_path() / RELIEF_IMAGE_LIBRARY_FROM_BIN).lexically_normal().string());
  paths.push_back(RELIEF_IMAGE_LIBRARY_BUILD_PATH);
  return paths;
}

Loaded load() {
  Loaded result;
  std::string reasons;
  for (const std::string& path : candidates()) {
    std::error_code ec;
    if (!fs::exists(path, ec)) {
      reasons += (reasons.empty() ? "" : "; ") + path + ": no such file";
      continue;
    }
    // RTLD_LOCAL: OpenImageIO's symbols stay out of the JIT's and the host's lookups.
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* err = ::dlerror();
      reasons += (reasons.empty() ? "" : "; ") + std::string(err ? err : path + ": cannot load");
      continue;
    }
    using Entry = const RlfImageLibrary* (*)();
    auto entry = reinterpret_cast<Entry>(::dlsym(handle, "rlf_image_library"));
    const RlfImageLibrary* table = entry ? entry() : nullptr;
    if (!table || table->version != RLF_IMAGE_LIBRARY_VERSION || table->size != sizeof(RlfImageLibrary)) {
      reasons += (reasons.empty() ? "" : "; ") + path + ": not a Relief image library of version " +
                 std::to_string(RLF_IMAGE_LIBRARY_VERSION) + " (a stale build?)";
      ::dlclose(handle);
      continue;
    }
    result.table = table;  // never closed: the TextureSystem lives as long as the process
    loadedFlag.store(true, std::memory_order_release);
    return result;
  }
  result.why = "cannot load the image library (OpenImageIO): " + reasons;
  return result;
}

}  // namespace

const RlfImageLibrary* imageLibrary(std::string* why) {
  static const Loaded loaded = load();
  if (!loaded.table && why) *why = loaded.why;
  return loaded.table;
}

bool imageLibraryLoaded() { return loadedFlag.load(std::memory_order_acquire); }

}  // namespace relief::runtime
