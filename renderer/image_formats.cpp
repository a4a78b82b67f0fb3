// PNG and PNM writers (see image_formats.h). PNG per the W3C PNG specification: signature, IHDR,
// optional sRGB and tEXt, IDAT holding the zlib stream of filtered scanlines, IEND; each chunk
// carries a CRC-32 of its type and data.
#include "renderer/image_formats.h"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>

namespace relief {
namespace {

// Closes the file on every path; close() reports the error a buffered write may only show there.
class OutFile {
 public:
  explicit OutFile(const std::string& path) : file_(std::fopen(path.c_str(), "wb")) {
    if (!file_) failure_ = std::strerror(errno);
  }
  ~OutFile() {
    if (file_) std::fclose(file_);
  }
  bool ok() const { return failure_.empty(); }
  void write(const void* data, size_t size) {
    if (ok() && size && std::fwrite(data, 1, size, file_) != size) failure_ = std::strerror(errno);
  }
  bool close(std::string* error) {
    if (file_ && std::fclose(file_) != 0 && ok()) failure_ = std::strerror(errno);
    file_ = nullptr;
    if (ok()) return true;
    *error = failure_;
    return false;
  }

 private:
  FILE* file_;
  std::string failure_;
};

void putU32(std::vector<uint8_t>& out, uint32_t v) {
  out.push_back(uint8_t(v >> 24)), out.push_back(uint8_t(v >> 16));
  out.push_back(uint8_t(v >> 8)), out.push_back(uint8_t(v));
}

void writeChunk(OutFile& file, const char type[4], const uint8_t* data, size_t size) {
  std::vector<uint8_t> head;
  putU32(head, uint32_t(size));
  head.insert(head.end(), type, type + 4);
  uLong crc = crc32(0L, reinterpret_cast<const Bytef*>(type), 4);
  if (size) crc = crc32(crc, data, uInt(size));
  std::vector<uint8_t> tail;
  putU32(tail, uint32_t(crc));
  file.write(head.data(), head.size());
  file.write(data, size);
  file.write(tail.data(), tail.size());
}

// PNG keywords: 1-79 printable Latin-1 characters, no leading, trailing or doubled spaces.
bool validKeyword(const std::string& k) {
  if (k.empty() || k.size() > 79 || k.front() == ' ' || k.back() == ' ') return false;
  for (size_t i = 0; i < k.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(k[i]);
    if (!((c >= 32 && c <= 126) || c >= 161)) return false;
    if (c == ' ' && i > 0 && k[i - 1] == ' ') return false;
  }
  return true;
}

uint8_t paeth(int a, int b, int c) {
  const int p = a + b - c;
  const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return uint8_t(pa <= pb && pa <= pc ? a : pb <= pc ? b : c);
}

// One scanline filtered with each of the five filters; keeps the one with the smallest sum of
// absolute signed bytes (the heuristic the PNG specification suggests). out: filter byte + row.
// Each filter runs its own loop: with a switch per byte, filtering took four times as long.
void filterRow(const uint8_t* row, const uint8_t* prev, size_t size, int bpp, std::vector<uint8_t>& out,
               std::vector<uint8_t>& trial) {
  trial.resize(size);
  uint64_t best = UINT64_MAX;
  const size_t start = out.size();
  const size_t lead = std::min(size, size_t(bpp));  // bytes with no left neighbour
  for (uint8_t filter = 0; filter < 5; ++filter) {
    uint8_t* t = trial.data();
    switch (filter) {
      case 0:
        std::memcpy(t, row, size);
        break;
      case 1:
        for (size_t i = 0; i < lead; ++i) t[i] = row[i];
        for (size_t i = lead; i < size; ++i) t[i] = uint8_t(row[i] - row[i - bpp]);
        break;
      case 2:
        for (size_t i = 0; i < size; ++i) t[i] = uint8_t(row[i] - (prev ? prev[i] : 0));
        break;
      case 3:
        for (size_t i = 0; i < lead; ++i) t[i] = uint8_t(row[i] - (prev ? prev[i] : 0) / 2);
        for (size_t i = lead; i < size; ++i) t[i] = uint8_t(row[i] - (row[i - bpp] + (prev ? prev[i] : 0)) / 2);
        break;
      default:
        for (size_t i = 0; i < lead; ++i) t[i] = uint8_t(row[i] - paeth(0, prev ? prev[i] : 0, 0));
        for (size_t i = lead; i < size; ++i)
          t[i] = uint8_t(row[i] - (prev ? paeth(row[i - bpp], prev[i], prev[i - bpp]) : paeth(row[i - bpp], 0, 0)));
        break;
    }
    uint64_t cost = 0;
    for (size_t i = 0; i < size; ++i) cost += uint64_t(std::abs(int(int8_t(t[i]))));
    if (cost < best) {
      best = cost;
      out.resize(start);
      out.push_back(filter);
      out.insert(out.end(), trial.begin(), trial.end());
    }
  }
}

// Rows per compressed band. Each band is a raw deflate stream primed with the 32 KB of filtered
// rows before it (so matches reach across the seam as in one stream) and ended by a sync flush, so
// the bands concatenate into one deflate stream; the zlib wrapper's Adler-32 covers all of them.
constexpr int kBandRows = 64;
constexpr size_t kDeflateWindow = size_t(1) << 15;

// Compresses data[begin, end) as one band; `last` ends the deflate stream. False on a zlib failure.
bool deflateBand(const std::vector<uint8_t>& data, size_t begin, size_t end, bool last,
                 std::vector<uint8_t>& out) {
  z_stream z{};
  if (deflateInit2(&z, 6, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY) != Z_OK) return false;
  const size_t primed = std::min(begin, kDeflateWindow);
  bool ok = primed == 0 || deflateSetDictionary(&z, data.data() + begin - primed, uInt(primed)) == Z_OK;
  out.resize(deflateBound(&z, uLong(end - begin)) + 16);
  z.next_in = const_cast<Bytef*>(data.data() + begin);
  z.avail_in = uInt(end - begin);
  z.next_out = out.data();
  z.avail_out = uInt(out.size());
  const int status = ok ? deflate(&z, last ? Z_FINISH : Z_SYNC_FLUSH) : Z_STREAM_ERROR;
  ok = ok && (last ? status == Z_STREAM_END : status == Z_OK) && z.avail_in == 0;
  out.resize(out.size() - z.avail_out);
  deflateEnd(&z);
  return ok;
}

}  // namespace

bool writePng(const std::string& path, const Image8& image, bool srgb, float gamma,
              const std::vector<std::pair<std::string, std::string>>& text, std::string* error,
              int threads) {
  static const uint8_t kColourType[5] = {0, 0, 4, 2, 6};
  if (image.channels < 1 || image.channels > 4 || image.width <= 0 || image.height <= 0) {
    *error = "PNG holds 1 to 4 channels";
    return false;
  }
  const size_t rowBytes = size_t(image.width) * size_t(image.channels);

  std::vector<uint8_t> filtered, trial;
  filtered.reserve(size_t(image.height) * (rowBytes + 1));
  for (int y = 0; y < image.height; ++y) {
    const uint8_t* row = image.pixels + size_t(y) * rowBytes;
    filterRow(row, y > 0 ? row - rowBytes : nullptr, rowBytes, image.channels, filtered, trial);
  }
  const int numBands = (image.height + kBandRows - 1) / kBandRows;
  std::vector<std::vector<uint8_t>> bands(static_cast<size_t>(numBands));
  std::atomic<int> nextBand{0};
  std::atomic<bool> zlibOk{true};
  auto work = [&] {
    for (int b; (b = nextBand.fetch_add(1)) < numBands && zlibOk.load();) {
      const size_t begin = size_t(b) * kBandRows * (rowBytes + 1);
      const size_t end = std::min(filtered.size(), begin + size_t(kBandRows) * (rowBytes + 1));
      if (!deflateBand(filtered, begin, end, b + 1 == numBands, bands[size_t(b)])) zlibOk = false;
    }
  };
  std::vector<std::thread> helpers;
  for (int t = 1; t < std::min(threads, numBands); ++t) helpers.emplace_back(work);
  work();
  for (std::thread& h : helpers) h.join();
  if (!zlibOk) {
    *error = "zlib compression failed";
    return false;
  }
  // The zlib stream: header (deflate, 32 KB window, default level), the bands, Adler-32.
  std::vector<uint8_t> compressed = {0x78, 0x9c};
  for (const std::vector<uint8_t>& band : bands) compressed.insert(compressed.end(), band.begin(), band.end());
  putU32(compressed, uint32_t(adler32_z(adler32_z(0, nullptr, 0), filtered.data(), filtered.size())));

  OutFile file(path);
  static const uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  file.write(kSignature, sizeof kSignature);
  std::vector<uint8_t> header;
  putU32(header, uint32_t(image.width));
  putU32(header, uint32_t(image.height));
  header.insert(header.end(), {8, kColourType[image.channels], 0, 0, 0});
  writeChunk(file, "IHDR", header.data(), header.size());
  // Colour: sRGB, with the gAMA and cHRM the PNG specification recommends beside it for readers
  // that do not know sRGB. Otherwise the power the values were encoded with: gamma 1 for data
  // (already mapped to [0, 1]), so nothing re-encodes it; 1/g for RiExposure's gamma g, so a
  // colour-managed viewer does not brighten it a second time.
  std::vector<uint8_t> gAMA;
  const double fileGamma = gamma > 0.0f && std::isfinite(gamma) ? 1.0 / double(gamma) : 1.0;
  putU32(gAMA, srgb ? 45455u : uint32_t(std::clamp(std::lround(100000.0 * fileGamma), 1L, 4000000000L)));
  if (srgb) {
    const uint8_t perceptual = 0;
    writeChunk(file, "sRGB", &perceptual, 1);
    std::vector<uint8_t> chromaticities;
    for (uint32_t v : {31270u, 32900u, 64000u, 33000u, 30000u, 60000u, 15000u, 6000u}) putU32(chromaticities, v);
    writeChunk(file, "cHRM", chromaticities.data(), chromaticities.size());
  }
  writeChunk(file, "gAMA", gAMA.data(), gAMA.size());
  std::vector<std::pair<std::string, std::string>> chunks = {{"Software", "relief"}};
  chunks.insert(chunks.end(), text.begin(), text.end());
  for (const auto& [keyword, value] : chunks) {
    if (!validKeyword(keyword)) continue;
    std::vector<uint8_t> data(keyword.begin(), keyword.end());
    data.push_back(0);
    for (char c : value)
      if (c != '\0') data.push_back(uint8_t(c));
    writeChunk(file, "tEXt", data.data(), data.size());
  }
  constexpr size_t kIdatBytes = size_t(1) << 20;
  for (size_t at = 0; at < compressed.size(); at += kIdatBytes)
    writeChunk(file, "IDAT", compressed.data() + at, std::min(kIdatBytes, compressed.size() - at));
  writeChunk(file, "IEND", nullptr, 0);
  return file.close(error);
}

bool writePnm(const std::string& path, const Image8& image, std::string* error) {
  if ((image.channels != 1 && image.channels != 3) || image.width <= 0 || image.height <= 0) {
    *error = "PNM holds 1 or 3 channels, no alpha";
    return false;
  }
  OutFile file(path);
  const std::string header = std::string(image.channels == 1 ? "P5\n" : "P6\n") + std::to_string(image.width) +
                             " " + std::to_string(image.height) + "\n255\n";
  file.write(header.data(), header.size());
  file.write(image.pixels, size_t(image.width) * size_t(image.height) * size_t(image.channels));
  return file.close(error);
}

}  // namespace relief
