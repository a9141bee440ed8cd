// Distance to the nearest object, collisions and time to collision: the official interaction_features_test cases
// (metrics-spec.md A3, A4) and hand-computed rounded-box distances.
#include "offline/eval/features/interactive.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ss {
namespace {

BoxState box(double x, double y, double length, double width, double heading = 0, bool valid = true) {
  BoxState b;
  b.x = x, b.y = y, b.length = length, b.width = width, b.heading = heading, b.height = 1, b.valid = valid;
  return b;
}

// One object per box list; each list is the object's frames.
std::vector<SceneObject> objects(std::vector<std::vector<BoxState>> frames) {
  std::vector<SceneObject> out;
  for (size_t i = 0; i < frames.size(); ++i) out.push_back({static_cast<int64_t>(i), ObjectType::vehicle, frames[i]});
  return out;
}

TEST(Interactive, OfficialDistanceConfigurations) {
  // [x, y, length, width, heading] pairs, one configuration per frame; box 1 is evaluated.
  const std::vector<BoxState> a = {box(0, 0, 2, 1), box(0, 0, 1, 1), box(0, 0, 2, 1, kPi / 2), box(6, 0, 2, 1, kPi)};
  const std::vector<BoxState> b = {box(3, 0, 4, 1), box(0, 1.5, 1, 2), box(1, 0, 1, 1), box(-6, 0, 2, 1)};
  const std::vector<int> eval = {0};
  const auto d = distance_to_nearest_object(objects({a, b}), eval);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_NEAR(d[0][0], 0.0, 1e-9);  // touching forward
  EXPECT_NEAR(d[0][1], 0.0, 1e-9);  // touching on the side
  EXPECT_NEAR(d[0][2], 0.0, 1e-9);  // touching, box 1 turned 90 degrees
  EXPECT_NEAR(d[0][3], 10.0, 1e-9);
}

TEST(Interactive, InvalidObjectsAreFarAway) {
  const std::vector<int> eval = {0};
  for (bool valid : {true, false}) {
    const auto d = distance_to_nearest_object(objects({{box(6, 0, 2, 1, kPi)}, {box(-6, 0, 2, 1, 0, valid)}}), eval);
    EXPECT_DOUBLE_EQ(d[0][0], valid ? 10.0 : kExtremelyLargeDistance);
  }
}

TEST(Interactive, SelectsNearestValid) {
  // Box 2 is 5 m away, box 3 10 m; frame 2 loses box 2.
  const auto o = objects({{box(0, 0, 1, 1), box(0, 0, 1, 1), box(0, 0, 1, 1)},
                          {box(6, 0, 1, 1), box(6, 0, 1, 1, 0, true), box(6, 0, 1, 1, 0, false)},
                          {box(0, 11, 1, 1), box(0, 11, 1, 1, 0, false), box(0, 11, 1, 1)}});
  const std::vector<int> eval = {0};
  const auto d = distance_to_nearest_object(o, eval);
  EXPECT_NEAR(d[0][0], 5.0, 1e-9);
  EXPECT_NEAR(d[0][1], 5.0, 1e-9);
  EXPECT_NEAR(d[0][2], 10.0, 1e-9);
}

TEST(Interactive, RoundedCornersAndPenetration) {
  // 2 x 2 squares: rounding radius 0.7, core half-side 0.3.
  // Diagonal neighbours: sharp corners would be sqrt(0.5) apart; the rounded ones are 1.9 sqrt(2) - 1.4 apart.
  EXPECT_NEAR(box_signed_distance(box(0, 0, 2, 2), box(2.5, 2.5, 2, 2)), 1.9 * std::sqrt(2.0) - 1.4, 1e-9);
  // Overlapping along one side: the rounded box behaves like the sharp one, -1 m.
  EXPECT_NEAR(box_signed_distance(box(0, 0, 4, 2), box(3, 0, 4, 2)), -1.0, 1e-9);
  // Cores overlapping by 0.4 (x) and 0.5 (y): penetration 0.4, minus both radii.
  EXPECT_NEAR(box_signed_distance(box(0, 0, 2, 2), box(0.2, 0.1, 2, 2)), -0.4 - 1.4, 1e-9);
  // Symmetric.
  EXPECT_NEAR(box_signed_distance(box(0.2, 0.1, 2, 2), box(0, 0, 2, 2)), -1.8, 1e-9);
}

TEST(Interactive, ConvexPolygonDistance) {
  const std::vector<Vec2> sq = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  const std::vector<Vec2> far = {{3, 0}, {4, 0}, {4, 1}, {3, 1}};
  const std::vector<Vec2> diag = {{2, 2}, {3, 2}, {3, 3}, {2, 3}};
  const std::vector<Vec2> in = {{0.75, 0.25}, {1.75, 0.25}, {1.75, 1.25}, {0.75, 1.25}};
  EXPECT_NEAR(convex_polygon_signed_distance(sq, far), 2.0, 1e-12);
  EXPECT_NEAR(convex_polygon_signed_distance(sq, diag), std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(convex_polygon_signed_distance(sq, in), -0.25, 1e-12);
}

// The official TTC cases: boxes at `xy` with `headings`, sizes and speeds; each box moves along its heading, so
// three frames give the central-difference speed at the middle one, where TTC is checked.
std::vector<double> ttc_case(std::vector<Vec2> xy, std::vector<double> headings, Vec2 size, std::vector<double> speeds) {
  std::vector<std::vector<BoxState>> frames;
  for (size_t i = 0; i < xy.size(); ++i) {
    std::vector<BoxState> f;
    for (int t = -1; t <= 1; ++t) {
      const double step = speeds[i] * 0.1 * t;
      f.push_back(box(xy[i].x + step * std::cos(headings[i]), xy[i].y + step * std::sin(headings[i]), size.x, size.y,
                      headings[i]));
    }
    frames.push_back(f);
  }
  std::vector<int> eval;
  for (size_t i = 0; i < xy.size(); ++i) eval.push_back(static_cast<int>(i));
  const auto ttc = time_to_collision(objects(frames), eval, 0.1);
  std::vector<double> mid;
  for (const auto& v : ttc) {
    EXPECT_DOUBLE_EQ(v[0], kMaxTimeToCollision);  // no speed at the ends
    mid.push_back(v[1]);
  }
  return mid;
}

void expect_near(const std::vector<double>& got, const std::vector<double>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < got.size(); ++i) EXPECT_NEAR(got[i], want[i], 1e-6) << "box " << i;
}

TEST(Interactive, TimeToCollisionGrid) {
  // 9 unit squares in a 3 x 3 grid, speeds 10, 6, 1 along each row.
  std::vector<Vec2> xy;
  std::vector<double> speeds;
  for (double y : {3.0, 0.0, -3.0})
    for (double x : {-3.0, 0.0, 3.0}) xy.push_back({x, y});
  for (int r = 0; r < 3; ++r) speeds.insert(speeds.end(), {10, 6, 1});
  const double m = kMaxTimeToCollision;
  expect_near(ttc_case(xy, std::vector<double>(9, 0.0), {1, 1}, speeds), {2. / 4, 2. / 5, m, 2. / 4, 2. / 5, m, 2. / 4, 2. / 5, m});
}

TEST(Interactive, TimeToCollisionLinedUp) {
  expect_near(ttc_case({{0, 0}, {5, 0}, {10, 0}, {15, 0}}, {0, 0, 0, 0}, {4, 2}, {6, 10, 3, 1}),
              {kMaxTimeToCollision, 1. / 7, 1. / 2, kMaxTimeToCollision});
}

TEST(Interactive, TimeToCollisionIgnoresMisaligned) {
  const double h = 75.0 * kPi / 180;
  expect_near(ttc_case({{0, 0}, {5, 0}, {10, 0}, {15, 0}}, {0, h + 0.01, 0, h - 0.01}, {4, 2}, {10, 6, 3, 1}),
              {6. / 7, kMaxTimeToCollision, (3 - std::cos(h - 0.01) * 2 - std::sin(h - 0.01)) / 2, kMaxTimeToCollision});
}

TEST(Interactive, TimeToCollisionIgnoresNoOverlap) {
  expect_near(ttc_case({{0, 0}, {5, 2.1}, {10, 1.1}, {15, 0}}, {0, 0, 0, 0}, {4, 2}, {10, 6, 3, 1}),
              {6. / 7, 1. / 3, 1. / 2, kMaxTimeToCollision});
}

TEST(Interactive, TimeToCollisionSmallOverlapNeedsAlignment) {
  const double h = 10.0 * kPi / 180;
  expect_near(ttc_case({{0, 0}, {5, 2.0}, {10, -2.0}}, {0, h + 0.01, -h + 0.01}, {4, 2}, {6, 3, 1}),
              {(8 - std::cos(h - 0.01) * 2 - std::sin(h - 0.01)) / 5, kMaxTimeToCollision, kMaxTimeToCollision});
}

}  // namespace
}  // namespace ss
