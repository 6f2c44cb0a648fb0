#include "msk/core/order_statistics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace {

/// Every rank's value from OrderStatistics against a full sort of the values.
void expectSortedValues(const std::vector<double>& values, const std::vector<size_t>& ranks) {
  const auto visit = [&](const auto& f) {
    for (double x : values) f(x);
  };
  const msk::OrderStatistics stats(visit);
  ASSERT_EQ(stats.count(), values.size());
  std::vector<double> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  const std::vector<double> got = stats.select(visit, ranks);
  ASSERT_EQ(got.size(), ranks.size());
  for (size_t r = 0; r < ranks.size(); ++r) EXPECT_EQ(got[r], sorted[ranks[r]]) << "rank " << ranks[r];
}

}  // namespace

// Values of both signs spread over many magnitudes, with many ties, zeros of both signs and values that share their
// leading bits (one bin holding most of them): every rank, first to last, is the sorted sequence's.
TEST(OrderStatistics, EveryRankIsTheSortedValue) {
  std::mt19937 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_int_distribution<int> exponent(-30, 30), coin(0, 9);
  std::vector<double> values;
  for (int i = 0; i < 20000; ++i) {
    const int kind = coin(rng);
    if (kind == 0)
      values.push_back(0.0);
    else if (kind == 1)
      values.push_back(-0.0);
    else if (kind == 2)
      values.push_back(1.0 + 1e-9 * normal(rng));  // one bin
    else if (kind == 3)
      values.push_back(std::round(4 * normal(rng)));  // ties
    else
      values.push_back(normal(rng) * std::ldexp(1.0, exponent(rng)));
  }
  std::vector<size_t> ranks;
  for (size_t r = 0; r < values.size(); r += 97) ranks.push_back(r);
  ranks.push_back(values.size() - 1);
  ranks.push_back(values.size() / 2);
  ranks.push_back(values.size() / 2);  // the same rank twice, and out of order
  expectSortedValues(values, ranks);
}

// A single value, and all values equal: the selection needs no spread.
TEST(OrderStatistics, ConstantAndSingleValues) {
  expectSortedValues({-3.5}, {0});
  expectSortedValues(std::vector<double>(1000, 2.25), {0, 499, 999});
}

TEST(OrderStatistics, NoValuesCountsZero) {
  const auto none = [](const auto&) {};
  EXPECT_EQ(msk::OrderStatistics(none).count(), 0u);
}
