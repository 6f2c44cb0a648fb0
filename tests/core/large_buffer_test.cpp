#include "msk/core/large_buffer.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>

// Buffers from 1 MiB up are their own 2 MiB-aligned mappings (but under a sanitizer); smaller ones come from
// std::allocator. Both hold their values through copies, growth and shrinking.
TEST(LargeBuffer, VectorsOfEverySizeKeepTheirValues) {
  for (size_t n : {size_t{0}, size_t{1}, size_t{1000}, size_t{262143}, size_t{262144}, size_t{3000000}}) {
    SCOPED_TRACE(n);
    msk::LargeVector<float> v(n);
    std::iota(v.begin(), v.end(), 0.0f);
    if (n * sizeof(float) >= msk::detail::kHugeFrom) {
      EXPECT_EQ(reinterpret_cast<uintptr_t>(v.data()) % msk::detail::kHugePage, 0u);
    }
    msk::LargeVector<float> copy = v;
    copy.resize(n + 300000, -1.0f);  // grows across the threshold for the smaller sizes
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(copy[i], static_cast<float>(i));
    EXPECT_EQ(copy.back(), -1.0f);
    copy.resize(n / 2);
    copy.shrink_to_fit();
    for (size_t i = 0; i < copy.size(); ++i) ASSERT_EQ(copy[i], v[i]);
  }
}
