#include "engine/scenario/validate.h"

#include <cmath>
#include <unordered_set>

#include "absl/strings/str_cat.h"
#include "engine/geometry/limits.h"

namespace ss {
namespace {

absl::Status bad(const std::string& where, const std::string& what) {
  return absl::InvalidArgumentError(absl::StrCat(where, ": ", what));
}

bool finite(double v) { return std::isfinite(v); }

absl::Status check_point(const std::string& where, const std::string& field, const MapPoint& p) {
  if (!finite(p.x) || !finite(p.y) || !finite(p.z))
    return bad(where, absl::StrCat(field, " has a non-finite coordinate (", p.x, ", ", p.y, ", ", p.z, ")"));
  if (std::abs(p.x) > kMaxCoordinate || std::abs(p.y) > kMaxCoordinate || std::abs(p.z) > kMaxCoordinate)
    return bad(where, absl::StrCat(field, " (", p.x, ", ", p.y, ", ", p.z, ") lies beyond ", kMaxCoordinate, " m"));
  return absl::OkStatus();
}

}  // namespace

absl::Status validate_scenario(const Scenario& s, const std::string& where) {
  const int frames = s.num_frames();
  if (frames == 0) return bad(where, "timestamps_seconds is empty: a scenario needs at least one frame");
  for (int i = 0; i < frames; ++i)
    if (!finite(s.timestamps[i])) return bad(where, absl::StrCat("timestamps_seconds[", i, "] is not finite"));
  if (s.current_time_index < 0 || s.current_time_index >= frames)
    return bad(where, absl::StrCat("current_time_index ", s.current_time_index, " is outside [0, ", frames, ")"));
  if (s.sdc_track_index < -1 || s.sdc_track_index >= static_cast<int>(s.tracks.size()))
    return bad(where, absl::StrCat("sdc_track_index ", s.sdc_track_index, " is outside the ", s.tracks.size(),
                                   " tracks"));

  std::unordered_set<int32_t> ids;
  for (size_t t = 0; t < s.tracks.size(); ++t) {
    const Track& tr = s.tracks[t];
    std::string name = absl::StrCat("tracks[", t, "] (id ", tr.id, ")");
    if (!ids.insert(tr.id).second) return bad(where, absl::StrCat(name, ": id is used by an earlier track"));
    int type = static_cast<int>(tr.type);
    if (type < 0 || type > 4) return bad(where, absl::StrCat(name, ": object_type ", type, " is not 0..4"));
    if (static_cast<int>(tr.states.size()) != frames)
      return bad(where, absl::StrCat(name, " has ", tr.states.size(), " states for ", frames, " frames"));
    for (int f = 0; f < frames; ++f) {
      const ObjectState& st = tr.states[f];
      if (!st.valid) continue;
      const std::pair<const char*, double> fields[] = {
          {"center_x", st.x},      {"center_y", st.y},       {"center_z", st.z},     {"length", st.length},
          {"width", st.width},     {"height", st.height},    {"heading", st.heading}, {"velocity_x", st.vx},
          {"velocity_y", st.vy}};
      for (const auto& [field, v] : fields)
        if (!finite(v)) return bad(where, absl::StrCat(name, " states[", f, "].", field, " is ", v));
      if (std::abs(st.x) > kMaxCoordinate || std::abs(st.y) > kMaxCoordinate || std::abs(st.z) > kMaxCoordinate)
        return bad(where, absl::StrCat(name, " states[", f, "] lies beyond ", kMaxCoordinate, " m"));
      if (std::abs(st.heading) > kMaxHeading)
        return bad(where, absl::StrCat(name, " states[", f, "].heading ", st.heading, " is beyond +-", kMaxHeading));
      if (st.length < 0 || st.width < 0 || st.height < 0)
        return bad(where, absl::StrCat(name, " states[", f, "] has a negative box size"));
    }
  }

  for (size_t i = 0; i < s.map_features.size(); ++i) {
    const MapFeature& mf = s.map_features[i];
    std::string name = absl::StrCat("map_features[", i, "] (id ", mf.id, ", ", map_feature_kind_name(mf.kind), ")");
    for (size_t p = 0; p < mf.points.size(); ++p)
      if (auto st = check_point(where, absl::StrCat(name, " point ", p), mf.points[p]); !st.ok()) return st;
    if (mf.kind == MapFeatureKind::lane && !finite(mf.lane.speed_limit_mph))
      return bad(where, absl::StrCat(name, " speed_limit_mph is not finite"));
  }

  if (!s.signals.empty() && static_cast<int>(s.signals.size()) != frames)
    return bad(where, absl::StrCat("dynamic_map_states has ", s.signals.size(), " entries for ", frames, " frames"));
  for (size_t f = 0; f < s.signals.size(); ++f)
    for (size_t k = 0; k < s.signals[f].size(); ++k) {
      const SignalLaneState& ls = s.signals[f][k];
      std::string name = absl::StrCat("dynamic_map_states[", f, "].lane_states[", k, "]");
      int st = static_cast<int>(ls.state);
      if (st < 0 || st > 8) return bad(where, absl::StrCat(name, ".state ", st, " is not 0..8"));
      if (auto e = check_point(where, name + ".stop_point", ls.stop_point); !e.ok()) return e;
    }

  for (size_t i = 0; i < s.tracks_to_predict.size(); ++i) {
    int ti = s.tracks_to_predict[i].track_index;
    if (ti < 0 || ti >= static_cast<int>(s.tracks.size()))
      return bad(where, absl::StrCat("tracks_to_predict[", i, "].track_index ", ti, " is outside the ",
                                     s.tracks.size(), " tracks"));
  }
  return absl::OkStatus();
}

}  // namespace ss
