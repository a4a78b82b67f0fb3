// Tests of image output: formats chosen by extension, sRGB encoding for 8-bit files, linear floats
// for EXR with metadata and named channels, the AOV display mappings, and atomic writes that leave
// nothing behind on failure.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <zlib.h>

#include "renderer/film.h"

namespace relief {
namespace {

namespace fs = std::filesystem;

fs::path scratch() {
  // OIIO's own worker threads (TIFF compression) are not instrumented, so TSan builds report
  // races inside them; these images are tiny, one thread does.
  OIIO::attribute("threads", 1);
  const fs::path dir = fs::temp_directory_path() /
                       ("relief-film-" + std::to_string(::getpid()) + "-" +
                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

Film testFilm() {
  Film film(3, 2);
  film.setPixel(0, 0, {0.0f, 0.5f, 1.0f});
  film.setPixel(2, 1, {2.0f, -1.0f, 0.25f});
  return film;
}

// Reads pixels as stored: 8-bit alpha files are not premultiplied on the way in.
std::vector<float> readBack(const fs::path& path, OIIO::TypeDesc type, int* channels) {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(path.string(), &config);
  EXPECT_TRUE(in) << OIIO::geterror();
  if (!in) return {};
  const OIIO::ImageSpec& spec = in->spec();
  *channels = spec.nchannels;
  std::vector<float> pixels(size_t(spec.width) * spec.height * spec.nchannels);
  if (type == OIIO::TypeDesc::UINT8) {
    std::vector<uint8_t> bytes(pixels.size());
    EXPECT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, bytes.data()));
    for (size_t i = 0; i < bytes.size(); ++i) pixels[i] = bytes[i];
  } else {
    EXPECT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels.data()));
  }
  return pixels;
}

TEST(FilmOutput, PngIsSrgbEncodedAndClamped) {
  const fs::path path = scratch() / "out.png";
  std::string error;
  ASSERT_TRUE(testFilm().write(path.string(), &error)) << error;
  int channels = 0;
  const std::vector<float> px = readBack(path, OIIO::TypeDesc::UINT8, &channels);
  ASSERT_EQ(channels, 3);
  ASSERT_EQ(px.size(), 18u);
  EXPECT_EQ(px[0], 0.0f);
  EXPECT_EQ(px[1], 188.0f);  // sRGB(0.5) = 0.7354
  EXPECT_EQ(px[2], 255.0f);
  EXPECT_EQ(px[15], 255.0f);  // 2.0 clamps
  EXPECT_EQ(px[16], 0.0f);    // negative clamps
  EXPECT_EQ(px[17], 137.0f);  // sRGB(0.25) = 0.5371
}

TEST(FilmOutput, ExrKeepsLinearFloats) {
  const fs::path path = scratch() / "out.exr";
  std::string error;
  ASSERT_TRUE(testFilm().write(path.string(), &error)) << error;
  int channels = 0;
  const std::vector<float> px = readBack(path, OIIO::TypeDesc::FLOAT, &channels);
  ASSERT_EQ(px.size(), 18u);
  EXPECT_EQ(px[1], 0.5f);
  EXPECT_EQ(px[15], 2.0f);
  EXPECT_EQ(px[16], -1.0f);
}

TEST(FilmOutput, AlphaChannel) {
  Film film(2, 1);
  film.setPixel(0, 0, {0.25f, 0.25f, 0.25f}, 0.5f);  // half-covered mid grey, premultiplied
  film.setPixel(1, 0, {0, 0, 0}, 0.0f);
  const fs::path dir = scratch();
  std::string error;
  ASSERT_TRUE(film.write((dir / "a.exr").string(), &error, true)) << error;
  int channels = 0;
  std::vector<float> px = readBack(dir / "a.exr", OIIO::TypeDesc::FLOAT, &channels);
  ASSERT_EQ(channels, 4);
  EXPECT_EQ(px[0], 0.25f);  // EXR keeps premultiplied colour
  EXPECT_EQ(px[3], 0.5f);
  ASSERT_TRUE(film.write((dir / "a.png").string(), &error, true)) << error;
  px = readBack(dir / "a.png", OIIO::TypeDesc::UINT8, &channels);
  ASSERT_EQ(channels, 4);
  EXPECT_EQ(px[0], 188.0f);  // straight colour 0.5, sRGB-encoded
  EXPECT_EQ(px[3], 128.0f);
  EXPECT_EQ(px[7], 0.0f);
}

TEST(FilmOutput, TiffIsWritten) {
  const fs::path path = scratch() / "out.tif";
  std::string error;
  ASSERT_TRUE(testFilm().write(path.string(), &error)) << error;
  int channels = 0;
  EXPECT_EQ(readBack(path, OIIO::TypeDesc::UINT8, &channels).size(), 18u);
}

TEST(FilmOutput, FailedWriteLeavesNoFile) {
  const fs::path dir = scratch();
  std::string error;
  EXPECT_FALSE(testFilm().write((dir / "missing" / "out.png").string(), &error));
  EXPECT_NE(error.find("out.png"), std::string::npos) << error;
  EXPECT_EQ(error.find(".tmp"), std::string::npos) << error;  // the staged name means nothing to users
  EXPECT_FALSE(testFilm().write((dir / "out.nosuchformat").string(), &error));
  // OpenImageIO's message names the staged temporary; the user sees the name they asked for.
  EXPECT_NE(error.find("out.nosuchformat"), std::string::npos) << error;
  EXPECT_EQ(error.find(".tmp"), std::string::npos) << error;
  EXPECT_FALSE(testFilm().write((dir / "noextension").string(), &error));
  EXPECT_TRUE(fs::is_empty(dir));
}

// A staged image committed onto a device (/dev/null) is written through it: renaming would have
// replaced the device with a regular file (as root, /dev/null itself).
TEST(FilmOutput, CommitOntoADeviceWritesThroughIt) {
  const fs::path dir = scratch();
  std::string staged, error;
  ASSERT_TRUE(testFilm().writeStaged((dir / "out.png").string(), &staged, &error, ImageWriteOptions{})) << error;
  ASSERT_TRUE(commitStagedImage(staged, "/dev/null", &error)) << error;
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
  EXPECT_TRUE(fs::is_empty(dir));  // the staged file is gone
}

TEST(FilmOutput, ReplacesAnExistingFile) {
  const fs::path path = scratch() / "out.png";
  std::string error;
  ASSERT_TRUE(testFilm().write(path.string(), &error)) << error;
  Film other(5, 4);
  ASSERT_TRUE(other.write(path.string(), &error)) << error;
  auto in = OIIO::ImageInput::open(path.string());
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().width, 5);
  EXPECT_EQ(std::distance(fs::directory_iterator(path.parent_path()), fs::directory_iterator()), 1);
}

TEST(FilmOutput, ExrCarriesMetadataAndNamedSingleChannel) {
  Film depth(2, 2);
  depth.setPixel(1, 0, glm::vec3(3.5f), 1.0f);
  const fs::path path = scratch() / "z.exr";
  ImageWriteOptions options;
  options.channels = 1;
  options.channelNames = {"Z"};
  options.metadata = {{"relief:scene", "scenes/x.rib"}, {"relief:cacheHits", "42"}};
  std::string error;
  ASSERT_TRUE(depth.write(path.string(), &error, options)) << error;
  auto in = OIIO::ImageInput::open(path.string());
  ASSERT_TRUE(in) << OIIO::geterror();
  const OIIO::ImageSpec& spec = in->spec();
  ASSERT_EQ(spec.nchannels, 1);
  EXPECT_EQ(spec.channelnames[0], "Z");
  EXPECT_EQ(spec.get_string_attribute("relief:scene"), "scenes/x.rib");
  EXPECT_EQ(spec.get_string_attribute("relief:cacheHits"), "42");
  std::vector<float> px(4);
  ASSERT_TRUE(in->read_image(0, 0, 0, 1, OIIO::TypeDesc::FLOAT, px.data()));
  EXPECT_EQ(px[1], 3.5f);
  EXPECT_EQ(px[0], 0.0f);
}

TEST(FilmOutput, LinearEightBitForData) {
  Film film(1, 1);
  film.setPixel(0, 0, glm::vec3(0.5f));
  const fs::path path = scratch() / "n.png";
  ImageWriteOptions options;
  options.srgb = false;
  std::string error;
  ASSERT_TRUE(film.write(path.string(), &error, options)) << error;
  int channels = 0;
  EXPECT_EQ(readBack(path, OIIO::TypeDesc::UINT8, &channels)[0], 128.0f);  // not 188
}

// PNG and PNM are written by Relief (renderer/image_formats.cpp), not OpenImageIO; OpenImageIO
// reads them back here as an independent decoder.
Film patternFilm(int width, int height, bool partialAlpha) {
  Film film(width, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const float a = partialAlpha ? float((x + 2 * y) % 5) / 4.0f : 1.0f;
      const glm::vec3 rgb(float(x) / float(width), float((x * y) % 7) / 6.0f, y % 3 == 0 ? 0.9f : float(y) / float(height));
      film.setPixel(x, y, rgb * a, a);
    }
  return film;
}

uint8_t expectedByte(float v, bool srgb) {
  const float encoded = srgb ? linearToSrgb(v) : std::clamp(v, 0.0f, 1.0f);
  return uint8_t(std::lround(encoded * 255.0f));
}

TEST(FilmOutput, PngAndPnmHoldEveryChannelLayoutExactly) {
  const fs::path dir = scratch();
  const int width = 37, height = 23;
  struct Case {
    const char* name;
    int channels;
    bool alpha, srgb;
  };
  for (const Case& c : {Case{"rgb.png", 3, false, true}, Case{"rgba.png", 3, true, true},
                        Case{"grey.png", 1, false, false}, Case{"greya.png", 1, true, true},
                        Case{"rgb.ppm", 3, false, true}, Case{"grey.pgm", 1, false, false}}) {
    SCOPED_TRACE(c.name);
    const Film film = patternFilm(width, height, c.alpha);
    ImageWriteOptions options;
    options.channels = c.channels;
    options.alpha = c.alpha;
    options.srgb = c.srgb;
    std::string error;
    ASSERT_TRUE(film.write((dir / c.name).string(), &error, options)) << error;
    int channels = 0;
    const std::vector<float> px = readBack(dir / c.name, OIIO::TypeDesc::UINT8, &channels);
    const int stored = c.channels + (c.alpha ? 1 : 0);
    ASSERT_EQ(channels, stored);
    ASSERT_EQ(px.size(), size_t(width * height * stored));
    int wrong = 0;
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        const float a = film.alpha(x, y);
        const glm::vec3 straight = film.pixel(x, y) * (c.alpha && a > 0.0f ? 1.0f / a : 1.0f);
        const float* p = &px[size_t(y * width + x) * size_t(stored)];
        for (int k = 0; k < c.channels; ++k) wrong += p[k] != expectedByte(straight[k], c.srgb);
        if (c.alpha) wrong += p[c.channels] != float(std::lround(a * 255.0f));
      }
    EXPECT_EQ(wrong, 0);
  }
}

// The filter byte of each row of a PNG file (the IDAT stream inflated).
std::vector<int> pngRowFilters(const fs::path& path, int rowBytes) {
  std::ifstream in(path, std::ios::binary);
  const std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string idat;
  for (size_t at = 8; at + 12 <= file.size();) {
    const auto byte = [&](size_t i) { return uint32_t(uint8_t(file[i])); };
    const uint32_t length = byte(at) << 24 | byte(at + 1) << 16 | byte(at + 2) << 8 | byte(at + 3);
    if (file.compare(at + 4, 4, "IDAT") == 0) idat += file.substr(at + 8, length);
    at += 12 + length;
  }
  std::vector<uint8_t> raw(size_t(rowBytes + 1) * 1024);  // up to 1024 rows
  uLongf size = uLongf(raw.size());
  EXPECT_EQ(uncompress(raw.data(), &size, reinterpret_cast<const Bytef*>(idat.data()), uLong(idat.size())), Z_OK);
  std::vector<int> filters;
  for (size_t row = 0; row * size_t(rowBytes + 1) < size; ++row) filters.push_back(raw[row * size_t(rowBytes + 1)]);
  return filters;
}

// Rows built so that each of PNG's five row filters is the writer's choice once (none for zeros,
// sub for a ramp, up for a repeated row, average for a row that is the mean of its left and upper
// neighbours, paeth for a sloped plane), and every one decodes back to the exact bytes.
TEST(FilmOutput, PngUsesAndDecodesEveryRowFilter) {
  const int width = 16;
  std::vector<std::vector<int>> rows(6, std::vector<int>(width, 0));
  for (int x = 0; x < width; ++x) rows[1][x] = rows[2][x] = 10 * x;
  for (int x = 0; x < width; ++x) rows[3][x] = ((x ? rows[3][x - 1] : 0) + rows[2][x]) / 2;
  for (int x = 0; x < width; ++x) rows[4][x] = 3 * x + 5, rows[5][x] = 3 * x + 10;
  Film film(width, int(rows.size()));
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < width; ++x) film.setPixel(x, y, glm::vec3(float(rows[y][x]) / 255.0f));
  ImageWriteOptions options;
  options.channels = 1;
  options.srgb = false;
  const fs::path path = scratch() / "filters.png";
  std::string error;
  ASSERT_TRUE(film.write(path.string(), &error, options)) << error;
  const std::vector<int> filters = pngRowFilters(path, width);
  EXPECT_EQ(filters, (std::vector<int>{0, 1, 2, 3, 1, 4}));
  int channels = 0;
  const std::vector<float> px = readBack(path, OIIO::TypeDesc::UINT8, &channels);
  ASSERT_EQ(px.size(), size_t(width) * rows.size());
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < width; ++x) EXPECT_EQ(px[size_t(y * width + x)], float(rows[y][x])) << x << "," << y;
}

// A PNG taller than one compression band (writePng compresses 64-row bands, several at once) and
// large enough for its 8-bit conversion to be split among threads: the same bytes whatever the
// thread count, one valid zlib stream (uncompress checks the Adler-32 over every band), and the
// exact pixels back.
TEST(FilmOutput, PngBandsGiveTheSameFileOnAnyThreadCount) {
  const int width = 331, height = 203;
  const Film film = patternFilm(width, height, false);
  const fs::path dir = scratch();
  auto bytesOf = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  std::string first;
  for (int threads : {1, 2, 3, 8}) {
    SCOPED_TRACE(threads);
    ImageWriteOptions options;
    options.threads = threads;
    const fs::path path = dir / ("bands" + std::to_string(threads) + ".png");
    std::string error;
    ASSERT_TRUE(film.write(path.string(), &error, options)) << error;
    const std::string bytes = bytesOf(path);
    if (first.empty()) first = bytes;
    EXPECT_EQ(bytes, first);
    EXPECT_EQ(pngRowFilters(path, width * 3).size(), size_t(height));  // every row inflated
  }
  int channels = 0;
  const std::vector<float> px = readBack(dir / "bands3.png", OIIO::TypeDesc::UINT8, &channels);
  ASSERT_EQ(channels, 3);
  ASSERT_EQ(px.size(), size_t(width * height * 3));
  int wrong = 0;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int k = 0; k < 3; ++k) wrong += px[size_t(y * width + x) * 3 + size_t(k)] != expectedByte(film.pixel(x, y)[k], true);
  EXPECT_EQ(wrong, 0);
}

TEST(FilmOutput, PngCarriesMetadataAndItsColourSpace) {
  const fs::path path = scratch() / "m.png";
  ImageWriteOptions options;
  options.metadata = {{"relief:scene", "scenes/x.rib"}, {"relief:cacheHits", "42"}, {" bad keyword", "skipped"}};
  std::string error;
  ASSERT_TRUE(testFilm().write(path.string(), &error, options)) << error;
  auto in = OIIO::ImageInput::open(path.string());
  ASSERT_TRUE(in) << OIIO::geterror();
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.get_string_attribute("relief:scene"), "scenes/x.rib");
  EXPECT_EQ(spec.get_string_attribute("relief:cacheHits"), "42");
  EXPECT_EQ(spec.get_string_attribute("Software"), "relief");
  EXPECT_EQ(spec.get_string_attribute("oiio:ColorSpace"), "sRGB");
}

TEST(FilmOutput, PpmIsBinaryP6) {
  const fs::path dir = scratch();
  std::string error;
  ASSERT_TRUE(testFilm().write((dir / "a.ppm").string(), &error)) << error;
  std::ifstream in(dir / "a.ppm", std::ios::binary);
  std::string magic, size;
  std::getline(in, magic);
  std::getline(in, size);
  EXPECT_EQ(magic, "P6");
  EXPECT_EQ(size, "3 2");
}

TEST(FilmOutput, AovDisplayMappings) {
  Film counts(3, 1);
  counts.setPixel(1, 0, glm::vec3(2.0f));
  counts.setPixel(2, 0, glm::vec3(6.0f));
  const Film heat = heatMapForDisplay(counts);
  EXPECT_EQ(heat.pixel(0, 0), glm::vec3(0.0f));  // no misses: black
  EXPECT_EQ(heat.pixel(2, 0), glm::vec3(1.0f));  // the most: white
  EXPECT_EQ(heat.pixel(1, 0), glm::vec3(1.0f, 0.0f, 0.0f));  // a third: red

  Film depth(3, 1);
  depth.setPixel(1, 0, glm::vec3(2.0f), 1.0f);
  depth.setPixel(2, 0, glm::vec3(4.0f), 1.0f);
  const Film grey = depthForDisplay(depth);
  EXPECT_EQ(grey.pixel(0, 0), glm::vec3(0.0f));  // a miss
  EXPECT_EQ(grey.pixel(1, 0), glm::vec3(1.0f));  // nearest: white
  EXPECT_NEAR(grey.pixel(2, 0).r, 0.2f, 1e-6f);   // farthest: dark grey, still unlike a miss

  Film normal(1, 1);
  normal.setPixel(0, 0, {0.0f, -1.0f, 1.0f}, 1.0f);
  EXPECT_EQ(normalForDisplay(normal).pixel(0, 0), glm::vec3(0.5f, 0.0f, 1.0f));
  EXPECT_TRUE(isFloatFormat("a/b.EXR"));
  EXPECT_FALSE(isFloatFormat("a/b.png"));
}

TEST(FilmOutput, SrgbTransfer) {
  EXPECT_EQ(linearToSrgb(0.0f), 0.0f);
  EXPECT_EQ(linearToSrgb(1.0f), 1.0f);
  EXPECT_EQ(linearToSrgb(std::nanf("")), 0.0f);
  EXPECT_NEAR(linearToSrgb(0.001f), 0.01292f, 1e-6f);
  EXPECT_NEAR(linearToSrgb(0.5f), 0.7354f, 1e-4f);
}

}  // namespace
}  // namespace relief
