#include "engine/map/focus.h"

namespace ss {

Vec2 scenario_focus(const Scenario& s) {
  const int now = s.current_time_index;
  if (s.sdc_track_index >= 0 && s.sdc_track_index < static_cast<int>(s.tracks.size())) {
    const Track& sdc = s.tracks[s.sdc_track_index];
    if (now < static_cast<int>(sdc.states.size()) && sdc.states[now].valid) return {sdc.states[now].x, sdc.states[now].y};
  }
  Vec2 sum;
  int n = 0;
  for (const Track& t : s.tracks)
    if (now < static_cast<int>(t.states.size()) && t.states[now].valid) sum = sum + Vec2{t.states[now].x, t.states[now].y}, ++n;
  if (n > 0) return (1.0 / n) * sum;
  for (const MapFeature& f : s.map_features)
    for (const MapPoint& p : f.points) sum = sum + Vec2{p.x, p.y}, ++n;
  return n > 0 ? (1.0 / n) * sum : Vec2{};
}

}  // namespace ss
