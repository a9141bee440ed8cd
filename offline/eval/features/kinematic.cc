#include "offline/eval/features/kinematic.h"

#include <cmath>
#include <limits>

#include "engine/geometry/geometry.h"

namespace ss {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// d[t] = f(t + 1, t - 1) for interior t, NaN at the ends.
template <typename F>
std::vector<double> central(size_t n, F f) {
  std::vector<double> d(n, kNaN);
  for (size_t t = 1; t + 1 < n; ++t) d[t] = f(t + 1, t - 1);
  return d;
}

}  // namespace

KinematicFeatures kinematic_features(std::span<const BoxState> s, double dt) {
  const size_t n = s.size();
  KinematicFeatures k;
  k.linear_speed = central(n, [&](size_t a, size_t b) {
    const double dx = s[a].x - s[b].x, dy = s[a].y - s[b].y, dz = s[a].z - s[b].z;
    return std::sqrt(dx * dx + dy * dy + dz * dz) / (2 * dt);
  });
  k.linear_acceleration = central(n, [&](size_t a, size_t b) {
    return (k.linear_speed[a] - k.linear_speed[b]) / (2 * dt);
  });
  // Half the heading change over two frames: the per-frame turn, which the acceleration differences again.
  const std::vector<double> dh = central(n, [&](size_t a, size_t b) { return wrap_angle(s[a].heading - s[b].heading) / 2; });
  k.angular_speed.resize(n);
  for (size_t t = 0; t < n; ++t) k.angular_speed[t] = dh[t] / dt;
  k.angular_acceleration = central(n, [&](size_t a, size_t b) {
    const double d = dh[a] - dh[b];
    return std::isnan(d) ? kNaN : wrap_angle(d) / 2 / (dt * dt);
  });
  return k;
}

std::vector<uint8_t> speed_validity(std::span<const uint8_t> valid) {
  const size_t n = valid.size();
  std::vector<uint8_t> out(n, 0);
  for (size_t i = 1; i + 1 < n; ++i) out[i] = valid[i - 1] && valid[i + 1];
  return out;
}

std::vector<uint8_t> acceleration_validity(std::span<const uint8_t> valid) {
  const std::vector<uint8_t> speed = speed_validity(valid);
  const size_t n = speed.size();
  std::vector<uint8_t> out(n, 0);
  for (size_t i = 1; i + 1 < n; ++i) out[i] = speed[i - 1] && speed[i + 1];
  return out;
}

}  // namespace ss
