#pragma once
/// Exact order statistics (medians, percentiles) of a long sequence of values without sorting or copying all of it:
/// one pass counts the values into 2¹⁶ bins by their leading bits, a second keeps only the values of the bins that
/// hold the wanted ranks and selects within them. The results are the same values std::nth_element gives on a copy of
/// the whole sequence. (std::nth_element on a copy of a whole image costs a copy and ~10 ns per voxel; neither Eigen
/// nor OpenCV offers an exact selection that avoids them.)
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/large_buffer.h"

namespace msk {

/// The order statistics of the values a visitor enumerates. `visit(f)` must call `f(double)` once per value, the
/// same values (in any order) every time it is called; the values must be finite.
class OrderStatistics {
 public:
  /// Counts the values into bins (the first pass).
  template <class Visit>
  explicit OrderStatistics(const Visit& visit) : counts_(kBins, 0) {
    visit([this](double x) { ++counts_[bin(x)]; });
    for (uint64_t c : counts_) count_ += c;
  }

  /// How many values there are.
  size_t count() const { return static_cast<size_t>(count_); }

  /// The values of 0-based ranks `ranks` in ascending order (each < count()), in the order of `ranks`: the
  /// (ranks[r]+1)-th smallest value for each r (the second pass).
  template <class Visit>
  std::vector<double> select(const Visit& visit, const std::vector<size_t>& ranks) const {
    for (size_t r : ranks) MSK_ASSERT(r < count_, "order statistic rank beyond the number of values");
    // Each rank's bin and its rank among that bin's values.
    std::vector<uint32_t> binOf(ranks.size());
    std::vector<size_t> rankInBin(ranks.size());
    std::vector<int32_t> slotOfBin(kBins, -1);
    std::vector<LargeVector<double>> slots;  // a bin can hold most values (an image's flat background)
    for (size_t r = 0; r < ranks.size(); ++r) {
      uint64_t below = 0;
      uint32_t b = 0;
      while (below + counts_[b] <= ranks[r]) below += counts_[b++];
      binOf[r] = b;
      rankInBin[r] = ranks[r] - static_cast<size_t>(below);
      if (slotOfBin[b] < 0) {
        slotOfBin[b] = static_cast<int32_t>(slots.size());
        slots.emplace_back();
        slots.back().reserve(static_cast<size_t>(counts_[b]));
      }
    }
    visit([&](double x) {
      const int32_t s = slotOfBin[bin(x)];
      if (s >= 0) slots[static_cast<size_t>(s)].push_back(x);
    });
    std::vector<double> out(ranks.size());
    for (size_t r = 0; r < ranks.size(); ++r) {
      LargeVector<double>& v = slots[static_cast<size_t>(slotOfBin[binOf[r]])];
      const auto at = v.begin() + static_cast<std::ptrdiff_t>(rankInBin[r]);
      std::nth_element(v.begin(), at, v.end());
      out[r] = *at;
    }
    return out;
  }

 private:
  static constexpr uint32_t kBins = 1u << 16;

  /// The bin of x: the leading 16 bits of its bit pattern mapped to an unsigned key in the order of the values
  /// (negative values' bits inverted, positive values' sign bit set).
  static uint32_t bin(double x) {
    uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    const uint64_t key = (bits >> 63) ? ~bits : bits | (uint64_t{1} << 63);
    return static_cast<uint32_t>(key >> 48);
  }

  std::vector<uint64_t> counts_;
  uint64_t count_ = 0;
};

}  // namespace msk
