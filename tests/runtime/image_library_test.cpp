// Tests of runtime/image_library.* through the texture builtin: the OpenImageIO plugin is loaded by
// the first texture lookup and not before, a lookup through it reads a real file, and a plugin that
// cannot be loaded becomes a reported texture failure with the reason, never a crash. Each test
// runs in a fresh process (a death test), because loading happens once per process.
#include "runtime/image_library.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "runtime/builtins_texture.h"

namespace relief::runtime {
namespace {

namespace fs = std::filesystem;

// A 2x2 PPM of one colour, (0.2, 0.4, 0.8) once decoded.
std::string writeTexture() {
  const fs::path path = fs::temp_directory_path() / ("relief-imagelib-" + std::to_string(::getpid()) + ".ppm");
  std::ofstream out(path, std::ios::binary);
  out << "P6\n2 2\n255\n";
  for (int i = 0; i < 4; ++i) out << char(51) << char(102) << char(204);
  return path.string();
}

// Whether a shared library whose name contains `name` is mapped into this process.
bool mapped(const std::string& name) {
  std::ifstream maps("/proc/self/maps");
  for (std::string line; std::getline(maps, line);)
    if (line.find(name) != std::string::npos) return true;
  return false;
}

// The bodies run in the child process and report through their exit code.
[[noreturn]] void lookUpThroughThePlugin() {
  // The runtime does not link OpenImageIO: only the lookup brings it in.
  if (imageLibraryLoaded() || mapped("libOpenImageIO")) std::_Exit(2);
  const std::string path = writeTexture();
  // Periodic wrap: a uniform texture then filters to its colour whatever the footprint.
  RlfTextureOptions options{};
  options.swidth = options.twidth = 1.0f;
  options.swrap = options.twrap = "periodic";
  float out[3], ds[3], dt[3];
  const int ok = rlf_texture(nullptr, path.c_str(), 0.25f, 0.75f, 0, 0, 0, 0, &options, 3, out, ds, dt);
  fs::remove(path);
  if (!ok) std::_Exit(3);
  if (!imageLibraryLoaded() || !mapped("libOpenImageIO")) std::_Exit(4);
  if (std::fabs(out[0] - 0.2f) > 1e-3f || std::fabs(out[1] - 0.4f) > 1e-3f || std::fabs(out[2] - 0.8f) > 1e-3f)
    std::fprintf(stderr, "got %g %g %g\n", out[0], out[1], out[2]), std::_Exit(5);
  std::_Exit(0);
}

[[noreturn]] void lookUpWithoutThePlugin() {
  ::setenv("RELIEF_IMAGE_LIBRARY", "/nonexistent/librelief_oiio.so", 1);
  const std::string path = writeTexture();
  RlfTextureOptions options{};
  options.fill = 0.5f;
  float out[1] = {-1}, ds[1], dt[1];
  const int ok = rlf_texture(nullptr, path.c_str(), 0.25f, 0.75f, 0, 0, 0, 0, &options, 1, out, ds, dt);
  fs::remove(path);
  std::string why;
  if (ok || out[0] != 0.5f || imageLibrary(&why) || why.find("/nonexistent/") == std::string::npos) std::_Exit(3);
  if (takeTextureFailures() != std::vector<std::string>{path}) std::_Exit(4);
  std::_Exit(0);
}

class ImageLibrary : public ::testing::Test {
 protected:
  void SetUp() override { GTEST_FLAG_SET(death_test_style, "threadsafe"); }
};

TEST_F(ImageLibrary, LoadsOnFirstTextureLookupOnly) {
  EXPECT_EXIT(lookUpThroughThePlugin(), ::testing::ExitedWithCode(0), "");
}

TEST_F(ImageLibrary, AnUnloadablePluginIsATextureFailureWithItsReason) {
  EXPECT_EXIT(lookUpWithoutThePlugin(), ::testing::ExitedWithCode(0),
              "cannot read texture .*cannot load the image library");
}

}  // namespace
}  // namespace relief::runtime
