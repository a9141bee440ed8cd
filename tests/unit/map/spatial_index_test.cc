#include "engine/map/spatial_index.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <utility>

#include <gtest/gtest.h>

namespace ss {
namespace {

MapSegment seg(double x, double y, double heading) {
  MapSegment s;
  s.pose = {x, y, heading};
  return s;
}

double d2(const MapSegment& s, Vec2 p) {
  double dx = p.x - s.pose.x, dy = p.y - s.pose.y;
  return dx * dx + dy * dy;
}

// Brute-force references; ties go to the lower index.
int brute_nearest(const std::vector<MapSegment>& segs, const Pose& pose, double max_diff) {
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  for (int i = 0; i < static_cast<int>(segs.size()); ++i) {
    if (max_diff < kPi && !(std::abs(wrap_angle(segs[i].pose.heading - pose.heading)) < max_diff)) continue;
    double d = d2(segs[i], {pose.x, pose.y});
    if (d < best_d) best_d = d, best = i;
  }
  return best;
}

std::vector<std::pair<double, int>> brute_sorted(const std::vector<MapSegment>& segs, Vec2 p) {
  std::vector<std::pair<double, int>> all;
  for (int i = 0; i < static_cast<int>(segs.size()); ++i) all.push_back({d2(segs[i], p), i});
  std::sort(all.begin(), all.end());
  return all;
}

std::vector<int> brute_within(const std::vector<MapSegment>& segs, Vec2 p, double r) {
  std::vector<int> out;
  for (auto [d, i] : brute_sorted(segs, p))
    if (d <= r * r) out.push_back(i);
  return out;
}

std::vector<int> brute_k(const std::vector<MapSegment>& segs, Vec2 p, int k) {
  std::vector<int> out;
  for (auto [d, i] : brute_sorted(segs, p))
    if (static_cast<int>(out.size()) < k) out.push_back(i);
  return out;
}

// Random segments over a WOMD-like area (thousands of metres from the origin), with clusters of exact duplicates
// so that ties occur.
std::vector<MapSegment> random_map(std::mt19937_64& rng, int n, double x0, double y0, double w, double h) {
  std::uniform_real_distribution<double> ux(x0, x0 + w), uy(y0, y0 + h), uh(-kPi, kPi);
  std::vector<MapSegment> segs;
  for (int i = 0; i < n; ++i) {
    if (i > 0 && i % 17 == 0) {
      segs.push_back(seg(segs[i - 1].pose.x, segs[i - 1].pose.y, uh(rng)));  // same centre as the previous one
    } else {
      segs.push_back(seg(ux(rng), uy(rng), uh(rng)));
    }
  }
  return segs;
}

void check_against_brute_force(const std::vector<MapSegment>& segs, double cell, int queries, uint64_t seed,
                                double x0, double y0, double w, double h) {
  SegmentIndex index(segs, cell);
  ASSERT_EQ(index.size(), static_cast<int>(segs.size()));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1), uh(-4, 4), ur(0, 80);
  const double filters[] = {kPi / 2, kPi, 0.3, 4.0, 0.0};
  const int ks[] = {1, 8, 128, static_cast<int>(segs.size()) + 3};
  for (int q = 0; q < queries; ++q) {
    Vec2 p;
    double kind = u01(rng);
    if (kind < 0.7) {  // in and around the map
      p = {x0 - 50 + (w + 100) * u01(rng), y0 - 50 + (h + 100) * u01(rng)};
    } else if (kind < 0.8 && !segs.empty()) {  // exactly on a centre: distance ties at 0
      const MapSegment& s = segs[static_cast<size_t>(u01(rng) * segs.size()) % segs.size()];
      p = {s.pose.x, s.pose.y};
    } else if (kind < 0.9) {  // far away, a few km
      p = {x0 + (u01(rng) - 0.5) * 2e4, y0 + (u01(rng) - 0.5) * 2e4};
    } else {  // very far away
      p = {(u01(rng) - 0.5) * 1e9, (u01(rng) - 0.5) * 1e9};
    }
    Pose pose{p.x, p.y, uh(rng)};
    for (double f : filters)
      ASSERT_EQ(index.nearest(pose, f), brute_nearest(segs, pose, f)) << "query " << q << " filter " << f;
    double r = ur(rng);
    ASSERT_EQ(index.within_radius(p, r), brute_within(segs, p, r)) << "query " << q << " radius " << r;
    int k = ks[q % 4];
    const std::vector<int> want = brute_k(segs, p, k);
    ASSERT_EQ(index.k_nearest(p, k), want) << "query " << q << " k " << k;
    std::vector<int> set = index.k_nearest_unordered(p, k), sorted_want = want;
    std::sort(set.begin(), set.end());
    std::sort(sorted_want.begin(), sorted_want.end());
    ASSERT_EQ(set, sorted_want) << "unordered, query " << q << " k " << k;
  }
}

TEST(SegmentIndex, MatchesBruteForceOnRandomMap) {
  std::mt19937_64 rng(1);
  auto segs = random_map(rng, 3000, 8000, -4000, 600, 400);
  check_against_brute_force(segs, 10.0, 4000, 2, 8000, -4000, 600, 400);
}

TEST(SegmentIndex, MatchesBruteForceWithOtherCellSizes) {
  std::mt19937_64 rng(3);
  auto segs = random_map(rng, 500, -300, 200, 300, 50);
  for (double cell : {0.7, 3.0, 25.0, 1000.0, 1e-6}) {
    SCOPED_TRACE(cell);
    check_against_brute_force(segs, cell, 500, 4, -300, 200, 300, 50);
  }
}

TEST(SegmentIndex, MatchesBruteForceOnSparseFarFlungMap) {
  // Two clusters 50 km apart: the cell count cap must keep the grid small and the answers exact.
  std::mt19937_64 rng(5);
  auto segs = random_map(rng, 200, 0, 0, 100, 100);
  auto far = random_map(rng, 200, 50000, 30000, 100, 100);
  segs.insert(segs.end(), far.begin(), far.end());
  check_against_brute_force(segs, 10.0, 1000, 6, 0, 0, 50100, 30100);
}

TEST(SegmentIndex, EmptyIndex) {
  SegmentIndex index({});
  EXPECT_EQ(index.size(), 0);
  EXPECT_EQ(index.nearest({1, 2, 0}), -1);
  EXPECT_EQ(index.nearest({1, 2, 0}, 10.0), -1);
  EXPECT_TRUE(index.within_radius({0, 0}, 1e9).empty());
  EXPECT_TRUE(index.k_nearest({0, 0}, 5).empty());
}

TEST(SegmentIndex, SingleSegment) {
  std::vector<MapSegment> segs = {seg(5000, -2000, 1.0)};
  SegmentIndex index(segs);
  EXPECT_EQ(index.nearest({0, 0, 1.0}), 0);
  EXPECT_EQ(index.nearest({0, 0, 1.0 + kPi}), -1);  // opposite heading is filtered
  EXPECT_EQ(index.nearest({1e12, -1e12, 1.0}), 0);
  EXPECT_EQ(index.within_radius({5000, -1990}, 10), std::vector<int>{0});
  EXPECT_TRUE(index.within_radius({5000, -1990}, 9.99).empty());
  EXPECT_EQ(index.k_nearest({-1e300, 1e300}, 3), std::vector<int>{0});
}

TEST(SegmentIndex, AllInOneCellTiesByIndex) {
  std::vector<MapSegment> segs;
  for (int i = 0; i < 50; ++i) segs.push_back(seg(100 + (i % 3) * 0.1, 200, i % 2 ? kPi : 0));
  SegmentIndex index(segs);
  EXPECT_EQ(index.nearest({100, 200, 0}), 0);
  EXPECT_EQ(index.nearest({100, 200, kPi}), 3);  // index 3 is the first odd one at x = 100
  EXPECT_EQ(index.nearest({100.2, 200, 0}), 2);
  auto k = index.k_nearest({100, 200}, 5);
  EXPECT_EQ(k, (std::vector<int>{0, 3, 6, 9, 12}));
  EXPECT_EQ(index.within_radius({100, 200}, 0).size(), 17u);  // every third, starting at 0
  for (int f = 0; f < 20; ++f) {
    Pose p{99.95 + 0.01 * f, 200.01, 0};
    EXPECT_EQ(index.nearest(p), brute_nearest(segs, p, kPi / 2));
  }
}

TEST(SegmentIndex, HeadingFilter) {
  std::vector<MapSegment> segs = {seg(0, 0, kPi), seg(10, 0, 0.5), seg(20, 0, -3.1)};
  SegmentIndex index(segs);
  EXPECT_EQ(index.nearest({0, 0, 0}), 1);           // the nearest points the other way
  EXPECT_EQ(index.nearest({0, 0, 0}, kPi), 0);      // pi: no filter, even an exactly opposite segment
  EXPECT_EQ(index.nearest({0, 0, 0}, 1e9), 0);
  EXPECT_EQ(index.nearest({0, 0, 3.1}, 0.1), 0);     // across the wrap: |wrap(pi - 3.1)| < 0.1
  EXPECT_EQ(index.nearest({0, 0, -3.05}, 0.06), 2);  // |wrap(pi + 3.05)| = 0.092 fails; -3.1 differs by 0.05
  EXPECT_EQ(index.nearest({0, 0, 0.5}, 0), -1);      // nothing differs by less than 0
  EXPECT_EQ(index.nearest({0, 0, 0.5 + 4 * kPi}), 1);  // headings are compared modulo 2 pi
}

TEST(SegmentIndex, CollinearAndDegenerateInputs) {
  std::vector<MapSegment> row;
  for (int i = 0; i < 100; ++i) row.push_back(seg(1e6 + i * 3.0, -7e5, 0));  // a grid one cell high
  SegmentIndex index(row);
  EXPECT_EQ(index.nearest({1e6 + 31, -7e5 + 500, 0}), 10);
  EXPECT_EQ(index.k_nearest({1e6 - 1, -7e5}, 3), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(index.within_radius({1e6 + 150, -7e5}, 3.0), (std::vector<int>{50, 49, 51}));

  // A bad cell size falls back to the default instead of failing.
  for (double cell : {0.0, -5.0, std::nan("")}) {
    SegmentIndex bad(row, cell);
    EXPECT_EQ(bad.nearest({1e6 + 31, -7e5, 0}), 10);
  }

  // A segment without a finite centre is never returned; non-finite queries find nothing.
  std::vector<MapSegment> with_nan = {seg(std::nan(""), 0, 0), seg(1, 1, 0), seg(INFINITY, 2, 0)};
  SegmentIndex n(with_nan);
  EXPECT_EQ(n.size(), 3);
  EXPECT_EQ(n.nearest({0, 0, 0}), 1);
  EXPECT_EQ(n.k_nearest({0, 0}, 5), std::vector<int>{1});
  EXPECT_EQ(n.within_radius({0, 0}, INFINITY), std::vector<int>{1});
  EXPECT_EQ(n.nearest({std::nan(""), 0, 0}), -1);
  EXPECT_TRUE(n.k_nearest({0, INFINITY}, 5).empty());
  EXPECT_TRUE(n.within_radius({0, 0}, -1).empty());
  EXPECT_TRUE(n.k_nearest({0, 0}, 0).empty());

  // Centres so far apart that their spread overflows a double.
  std::vector<MapSegment> extreme = {seg(-1.5e308, 0, 0), seg(1.5e308, 0, 0), seg(0, 0, 0)};
  SegmentIndex e(extreme);
  EXPECT_EQ(e.nearest({1, 0, 0}), 2);
  EXPECT_EQ(e.k_nearest({1, 0}, 1), std::vector<int>{2});
  EXPECT_EQ(e.within_radius({1, 0}, 5), std::vector<int>{2});
}

}  // namespace
}  // namespace ss
