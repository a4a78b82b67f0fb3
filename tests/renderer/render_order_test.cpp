// Tests of the pixel orders: each is a permutation of the image, and the Hilbert curve stays
// coherent (almost every step moves to a 4-neighbour) for any size, odd ones included.
#include <cstdlib>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/render.h"

namespace relief {
namespace {

void expectPermutation(const std::vector<uint32_t>& order, int w, int h) {
  ASSERT_EQ(order.size(), size_t(w) * size_t(h));
  std::vector<int> seen(order.size(), 0);
  for (uint32_t p : order) {
    ASSERT_LT(p, order.size());
    ++seen[p];
  }
  for (size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], 1) << "pixel " << i;
}

const std::vector<std::pair<int, int>> kSizes = {{1, 1},  {1, 9},   {9, 1},   {2, 2},
                                                 {7, 5},  {5, 7},   {13, 3},  {33, 17},
                                                 {64, 64}, {160, 120}, {97, 131}, {17, 100}};

TEST(RenderOrder, EveryOrderIsAPermutation) {
  for (PixelOrder order : {PixelOrder::Scanline, PixelOrder::Bucket, PixelOrder::Hilbert})
    for (auto [w, h] : kSizes) {
      SCOPED_TRACE(std::string(pixelOrderName(order)) + " " + std::to_string(w) + "x" +
                   std::to_string(h));
      expectPermutation(pixelOrder(order, w, h), w, h);
    }
}

TEST(RenderOrder, HilbertStepsAreLocal) {
  for (auto [w, h] : kSizes) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    const std::vector<uint32_t> order = pixelOrder(PixelOrder::Hilbert, w, h);
    int diagonal = 0;
    for (size_t i = 1; i < order.size(); ++i) {
      const int dx = std::abs(int(order[i] % w) - int(order[i - 1] % w));
      const int dy = std::abs(int(order[i] / w) - int(order[i - 1] / w));
      ASSERT_LE(dx, 1);
      ASSERT_LE(dy, 1);
      if (dx + dy == 2) ++diagonal;
    }
    // Odd-by-odd leftovers may force a few diagonal steps, never many.
    EXPECT_LE(diagonal, 1 + (w + h) / 8);
    EXPECT_EQ(order.front(), 0u);  // starts in a corner
  }
}

TEST(RenderOrder, HilbertOfAPowerOfTwoSquareHasOnlyUnitSteps) {
  const std::vector<uint32_t> order = pixelOrder(PixelOrder::Hilbert, 32, 32);
  for (size_t i = 1; i < order.size(); ++i) {
    const int dx = std::abs(int(order[i] % 32) - int(order[i - 1] % 32));
    const int dy = std::abs(int(order[i] / 32) - int(order[i - 1] / 32));
    EXPECT_EQ(dx + dy, 1) << "step " << i;
  }
}

TEST(RenderOrder, BucketsAre16x16Tiles) {
  const std::vector<uint32_t> order = pixelOrder(PixelOrder::Bucket, 40, 20);
  // The first tile is complete before the second starts.
  for (int i = 0; i < 256; ++i) {
    EXPECT_LT(order[size_t(i)] % 40, 16u);
    EXPECT_LT(order[size_t(i)] / 40, 16u);
  }
  EXPECT_EQ(order[256], 16u);
}

TEST(RenderOrder, ParsesNames) {
  PixelOrder o;
  EXPECT_TRUE(parsePixelOrder("bucket", &o));
  EXPECT_EQ(o, PixelOrder::Bucket);
  EXPECT_TRUE(parsePixelOrder("hilbert", &o));
  EXPECT_EQ(o, PixelOrder::Hilbert);
  EXPECT_FALSE(parsePixelOrder("spiral", &o));
}

}  // namespace
}  // namespace relief
