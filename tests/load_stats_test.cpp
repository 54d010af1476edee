// The load tester's percentiles (loadtest/load_stats): the figures its table, JSON, SVG and
// --sweep report.
#include "loadtest/load_stats.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace vox::loadtest {
namespace {

// No samples: every figure 0 and a count of 0, which callers must look at (0 ms is not a
// measurement).
TEST(Percentiles, NoSamplesGiveZeroesAndACountOfZero) {
  const Percentiles p = percentiles({});
  EXPECT_EQ(p.count, 0u);
  EXPECT_EQ(p.p50, 0);
  EXPECT_EQ(p.p95, 0);
  EXPECT_EQ(p.p99, 0);
  EXPECT_EQ(p.max, 0);
}

TEST(Percentiles, OneSampleIsEveryPercentile) {
  const Percentiles p = percentiles({42.5});
  EXPECT_EQ(p.count, 1u);
  EXPECT_EQ(p.p50, 42.5);
  EXPECT_EQ(p.p95, 42.5);
  EXPECT_EQ(p.p99, 42.5);
  EXPECT_EQ(p.max, 42.5);
}

TEST(Percentiles, DoNotDependOnTheOrderOfTheSamples) {
  std::vector<double> v;
  for (int i = 1; i <= 1000; ++i) v.push_back(i * 0.5);
  const Percentiles sorted = percentiles(v);
  std::mt19937 rng(3);
  std::shuffle(v.begin(), v.end(), rng);
  const Percentiles shuffled = percentiles(v);
  EXPECT_EQ(shuffled.p50, sorted.p50);
  EXPECT_EQ(shuffled.p95, sorted.p95);
  EXPECT_EQ(shuffled.p99, sorted.p99);
  EXPECT_EQ(shuffled.max, 500);
}

TEST(Percentiles, AreSamplesInOrderUpToTheMaximum) {
  std::mt19937 rng(7);
  std::exponential_distribution<double> latency(0.1);
  for (const size_t n : {2u, 3u, 7u, 99u, 101u, 1000u, 12345u}) {
    std::vector<double> v(n);
    for (auto& x : v) x = latency(rng);
    const Percentiles p = percentiles(v);
    EXPECT_EQ(p.count, n);
    EXPECT_LE(p.p50, p.p95) << n;
    EXPECT_LE(p.p95, p.p99) << n;
    EXPECT_LE(p.p99, p.max) << n;
    EXPECT_EQ(p.max, *std::max_element(v.begin(), v.end())) << n;
    for (const double q : {p.p50, p.p95, p.p99})
      EXPECT_NE(std::find(v.begin(), v.end(), q), v.end()) << "a percentile is a sample";
  }
}

// Regression: the percentile took the sample at index floor(q*n), one rank too high
// whenever q*n is whole: p99 of 100 samples was the maximum, and 10 slow edits in 1,000
// (1 %) made the p99 theirs. A pXX is the nearest rank: the smallest sample that at least
// XX % of the samples do not exceed (rank ceil(q*n)).
TEST(Percentiles, P99OfAHundredSamplesIsTheNinetyNinthNotTheMaximum) {
  std::vector<double> hundred;
  for (int i = 1; i <= 100; ++i) hundred.push_back(i);
  const Percentiles p = percentiles(hundred);
  EXPECT_EQ(p.p50, 50);
  EXPECT_EQ(p.p95, 95);
  EXPECT_EQ(p.p99, 99);
  EXPECT_EQ(p.max, 100);

  std::vector<double> edits(990, 1.0);
  edits.insert(edits.end(), 10, 100.0);  // exactly 1 % slow
  EXPECT_EQ(percentiles(edits).p99, 1.0);
  edits.push_back(100.0);  // just over 1 %
  EXPECT_EQ(percentiles(edits).p99, 100.0);
  // Ranks near the top of small and odd counts.
  EXPECT_EQ(percentiles({1, 2}).p50, 1);
  EXPECT_EQ(percentiles({1, 2, 3}).p50, 2);
  EXPECT_EQ(percentiles({1, 2, 3}).p99, 3);
}

}  // namespace
}  // namespace vox::loadtest
