#include "offline/eval/scene_features.h"

#include <cmath>

#include "offline/eval/features/interactive.h"
#include "offline/eval/features/kinematic.h"

namespace ss {

EvalMap EvalMap::from_scenario(const Scenario& s) {
  EvalMap m;
  m.road_edges = RoadEdges::from_scenario(s);
  m.surface_lanes = surface_street_lanes(s);
  m.signals = s.signals;
  return m;
}

namespace {

template <typename T>
std::vector<T> future(const std::vector<T>& v, int current_frame) {
  return std::vector<T>(v.begin() + std::min<size_t>(v.size(), current_frame + 1), v.end());
}

}  // namespace

SceneFeatures scene_features(const JointScene& scene, std::span<const int> evaluated, const EvalMap& map,
                             int current_frame, const JointScene* log, std::span<const int> log_evaluated) {
  SceneFeatures f;
  auto& v = f.values;
  for (int i : evaluated) {
    const SceneObject& o = scene.objects[i];
    KinematicFeatures k = kinematic_features(o.states, kEvalFrameSeconds);
    v[kLinearSpeed].push_back(future(k.linear_speed, current_frame));
    v[kLinearAcceleration].push_back(future(k.linear_acceleration, current_frame));
    v[kAngularSpeed].push_back(future(k.angular_speed, current_frame));
    v[kAngularAcceleration].push_back(future(k.angular_acceleration, current_frame));
    std::vector<uint8_t> valid;
    for (const BoxState& b : o.states) valid.push_back(b.valid);
    f.valid.push_back(future(valid, current_frame));
  }
  for (auto& d : distance_to_nearest_object(scene.objects, evaluated)) {
    std::vector<double> hit;
    for (double x : d) hit.push_back(x < 0 ? 1.0 : 0.0);  // a collision is a strictly negative distance
    v[kDistanceToNearestObject].push_back(future(d, current_frame));
    v[kCollision].push_back(future(hit, current_frame));
  }
  for (auto& t : time_to_collision(scene.objects, evaluated, kEvalFrameSeconds))
    v[kTimeToCollision].push_back(future(t, current_frame));
  for (auto& d : distance_to_road_edge(scene.objects, evaluated, map.road_edges)) {
    std::vector<double> off;
    for (double x : d) off.push_back(x > 0 ? 1.0 : 0.0);
    v[kDistanceToRoadEdge].push_back(future(d, current_frame));
    v[kOffroad].push_back(future(off, current_frame));
  }
  for (auto& l : traffic_light_violation(scene.objects, evaluated, map.surface_lanes, map.signals))
    v[kTrafficLightViolation].push_back(future(std::vector<double>(l.begin(), l.end()), current_frame));

  if (log) {
    for (size_t e = 0; e < evaluated.size(); ++e) {
      const auto& sim = scene.objects[evaluated[e]].states;
      const auto& ref = log->objects[log_evaluated[e]].states;
      double sum = 0;
      int n = 0;
      std::vector<double> d;
      for (size_t t = 0; t < ref.size() && t < sim.size(); ++t) {
        double e = std::nan("");
        if (ref[t].valid) {
          const double dx = sim[t].x - ref[t].x, dy = sim[t].y - ref[t].y, dz = sim[t].z - ref[t].z;
          e = std::sqrt(dx * dx + dy * dy + dz * dz);
          sum += e;
          ++n;
        }
        d.push_back(e);
      }
      f.ade.push_back(n ? sum / n : std::nan(""));
      f.displacement.push_back(future(d, current_frame));
    }
  }
  return f;
}

}  // namespace ss
