#include "offline/eval/joint_scene.h"

#include <algorithm>

namespace ss {

BoxState box_state(const ObjectState& s) {
  return {s.x, s.y, s.z, s.heading, s.length, s.width, s.height, s.valid};
}

namespace {

bool valid_at(const Track& t, int frame) {
  return frame >= 0 && frame < static_cast<int>(t.states.size()) && t.states[frame].valid;
}

}  // namespace

const char* sdc_rule_name(SdcRule r) { return r == SdcRule::model ? "model" : "log"; }

EvaluatedObjects evaluated_objects(const Scenario& s, SdcRule sdc) {
  const int now = s.current_time_index;
  EvaluatedObjects out;
  auto add = [&](int i) {
    if (i < 0 || i >= static_cast<int>(s.tracks.size()) || !valid_at(s.tracks[i], now)) return;
    if (std::find(out.tracks.begin(), out.tracks.end(), i) == out.tracks.end()) out.tracks.push_back(i);
  };
  // A scenario that names its SDC but no track to predict (the 20 s files) is scored on every agent, like one that
  // names neither: WOSAC's evaluated set is "the SDC plus tracks_to_predict", and without the second it says nothing.
  for (const RequiredPrediction& r : s.tracks_to_predict) add(r.track_index);
  out.named_by_scenario = !out.tracks.empty();
  if (out.named_by_scenario) add(s.sdc_track_index);
  else out.tracks = sim_agent_tracks(s);
  if (sdc == SdcRule::log) std::erase(out.tracks, s.sdc_track_index);
  std::stable_sort(out.tracks.begin(), out.tracks.end(),
                   [&](int a, int b) { return s.tracks[a].id < s.tracks[b].id; });
  return out;
}

std::vector<int> sim_agent_tracks(const Scenario& s) {
  std::vector<int> out;
  for (size_t i = 0; i < s.tracks.size(); ++i)
    if (valid_at(s.tracks[i], s.current_time_index)) out.push_back(static_cast<int>(i));
  return out;
}

JointScene log_scene(const Scenario& s, const std::vector<int>& tracks) {
  const int now = s.current_time_index;
  JointScene scene;
  for (int i : tracks) {
    const Track& t = s.tracks[i];
    SceneObject o;
    o.id = t.id;
    o.type = t.type;
    o.states.resize(s.num_frames());
    const ObjectState& at_now = t.states[now];
    for (int f = 0; f < s.num_frames() && f < static_cast<int>(t.states.size()); ++f) {
      o.states[f] = box_state(t.states[f]);
      if (f > now) {
        o.states[f].length = at_now.length;
        o.states[f].width = at_now.width;
        o.states[f].height = at_now.height;
      }
    }
    scene.objects.push_back(std::move(o));
  }
  return scene;
}

std::vector<int> scene_indices(const std::vector<int>& tracks_in_scene, const std::vector<int>& tracks) {
  std::vector<int> out;
  for (int t : tracks) {
    auto it = std::find(tracks_in_scene.begin(), tracks_in_scene.end(), t);
    out.push_back(it == tracks_in_scene.end() ? -1 : static_cast<int>(it - tracks_in_scene.begin()));
  }
  return out;
}

}  // namespace ss
