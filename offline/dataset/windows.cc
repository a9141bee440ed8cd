#include "offline/dataset/windows.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <unordered_map>

#include "absl/strings/str_cat.h"
#include "offline/dataset/dataset_rng.h"

namespace ss {
namespace {

enum class IncidentKind { collision, teleport, implausible };

struct IncidentFrame {
  int frame;
  IncidentKind kind;
};

// Per track (index into fcd.tracks): the frames of its collisions and teleports (SUMO's reports) and of motion no
// real agent makes (found here).
std::vector<std::vector<IncidentFrame>> incident_frames(const FcdRecording& fcd, const std::vector<Incident>& incidents,
                                                        const WindowOptions& o) {
  std::vector<std::vector<IncidentFrame>> out(fcd.tracks.size());
  std::unordered_map<std::string_view, int> index;
  for (size_t i = 0; i < fcd.tracks.size(); ++i) index.emplace(fcd.tracks[i].id, static_cast<int>(i));
  for (const Incident& inc : incidents) {
    auto it = index.find(inc.agent);
    if (it != index.end())
      out[it->second].push_back({fcd.frame_of(inc.time), inc.teleport ? IncidentKind::teleport : IncidentKind::collision});
  }
  const double j2 = o.jump_distance * o.jump_distance;
  for (size_t i = 0; i < fcd.tracks.size(); ++i) {
    const FcdTrack& t = fcd.tracks[i];
    const bool turns_like_a_vehicle = t.kind.type != ObjectType::pedestrian;  // pedestrians turn on the spot
    for (size_t k = 1; k < t.states.size(); ++k) {
      const FcdState &a = t.states[k - 1], &b = t.states[k];
      if (!a.valid || !b.valid) continue;
      const double yaw_rate = std::abs(wrap_angle(b.heading - a.heading)) / fcd.step;
      if ((b.x - a.x) * (b.x - a.x) + (b.y - a.y) * (b.y - a.y) > j2 ||
          (turns_like_a_vehicle && std::max(a.speed, b.speed) * yaw_rate > o.max_lateral_acceleration))
        out[i].push_back({t.first_frame + static_cast<int>(k), IncidentKind::implausible});
    }
  }
  return out;
}

class Cutter {
 public:
  Cutter(const SumoMap& map, const FcdRecording& fcd, const SignalTimeline& signals,
         const std::vector<Incident>& incidents, const WindowOptions& o, uint64_t seed, const std::string& prefix)
      : map_(map), fcd_(fcd), signals_(signals), o_(o), rng_(dataset_rng(seed)), prefix_(prefix),
        incidents_(incident_frames(fcd, incidents, o)) {}

  WindowCut run() {
    const int stride = std::max(1, static_cast<int>(std::lround(o_.stride / fcd_.step)));
    for (int s0 = 0; s0 + o_.frames <= fcd_.frames; s0 += stride) {
      ++cut_.windows;
      for (int ego : pick_egos(s0)) add_scenario(s0, ego);
    }
    return std::move(cut_);
  }

 private:
  // The first incident of track `t` within frames [s0, s0 + frames), or nullptr.
  const IncidentFrame* incident_in(int t, int s0) const {
    for (const IncidentFrame& f : incidents_[t])
      if (f.frame >= s0 && f.frame < s0 + o_.frames) return &f;
    return nullptr;
  }

  std::vector<int> pick_egos(int s0) {
    std::vector<int> candidates;
    const int cur = s0 + o_.current_frame;
    for (size_t i = 0; i < fcd_.tracks.size(); ++i) {
      const FcdTrack& t = fcd_.tracks[i];
      if (t.kind.type != ObjectType::vehicle || !t.at(s0) || !t.at(s0 + o_.frames - 1)) continue;
      bool whole = true;  // present in every frame (a teleport leaves a gap)
      for (int f = s0; f < s0 + o_.frames && whole; ++f) whole = t.at(f) != nullptr;
      if (!whole || t.at(cur)->speed < o_.min_ego_speed || incident_in(static_cast<int>(i), s0)) continue;
      candidates.push_back(static_cast<int>(i));
    }
    rng_.shuffle(&candidates);
    std::vector<int> egos;
    const double sep2 = o_.ego_separation * o_.ego_separation;
    for (int c : candidates) {
      if (static_cast<int>(egos.size()) >= o_.egos_per_window) break;
      const FcdState* p = fcd_.tracks[c].at(cur);
      bool apart = true;
      for (int e : egos) {
        const FcdState* q = fcd_.tracks[e].at(cur);
        apart = apart && (p->x - q->x) * (p->x - q->x) + (p->y - q->y) * (p->y - q->y) > sep2;
      }
      if (apart) egos.push_back(c);
    }
    return egos;
  }

  void add_scenario(int s0, int ego) {
    const int n = o_.frames;
    const FcdTrack& e = fcd_.tracks[ego];
    const double r2 = o_.radius * o_.radius;
    struct Seen {
      int rank;        // 0 for the ego
      double min_d2;   // closest approach to the ego
      int track;
      std::vector<char> in_range;
    };
    std::vector<Seen> seen;
    for (size_t i = 0; i < fcd_.tracks.size(); ++i) {
      const FcdTrack& t = fcd_.tracks[i];
      const int last = t.first_frame + static_cast<int>(t.states.size()) - 1;
      if (last < s0 || t.first_frame >= s0 + n) continue;
      Seen s{static_cast<int>(i) == ego ? 0 : 1, 1e300, static_cast<int>(i), std::vector<char>(n, 0)};
      bool any = false;
      for (int k = 0; k < n; ++k) {
        const FcdState* a = t.at(s0 + k);
        if (!a) continue;
        const FcdState* c = e.at(s0 + k);
        const double d2 = (a->x - c->x) * (a->x - c->x) + (a->y - c->y) * (a->y - c->y);
        if (d2 <= r2) {
          s.in_range[k] = 1;
          s.min_d2 = std::min(s.min_d2, d2);
          any = true;
        }
      }
      if (any) seen.push_back(std::move(s));
    }
    std::sort(seen.begin(), seen.end(), [](const Seen& a, const Seen& b) {
      return std::tie(a.rank, a.min_d2, a.track) < std::tie(b.rank, b.min_d2, b.track);
    });
    if (static_cast<int>(seen.size()) > o_.max_tracks) seen.resize(o_.max_tracks);
    for (const Seen& s : seen) {
      if (const IncidentFrame* f = incident_in(s.track, s0)) {
        ++(f->kind == IncidentKind::collision  ? cut_.dropped_collision
           : f->kind == IncidentKind::teleport ? cut_.dropped_teleport
                                               : cut_.dropped_implausible);
        return;
      }
    }

    Scenario sc;
    sc.id = absl::StrCat(prefix_, "_f", s0, "_", e.id);
    sc.timestamps.resize(n);
    for (int k = 0; k < n; ++k) sc.timestamps[k] = std::round(k * fcd_.step * 1e6) / 1e6;
    sc.current_time_index = o_.current_frame;
    sc.sdc_track_index = 0;
    for (const Seen& s : seen) {
      const FcdTrack& t = fcd_.tracks[s.track];
      Track tr;
      tr.id = s.track;
      tr.type = t.kind.type;
      tr.states.resize(n);
      for (int k = 0; k < n; ++k) {
        if (!s.in_range[k]) continue;
        const FcdState* a = t.at(s0 + k);
        ObjectState& o = tr.states[k];
        o.x = a->x;
        o.y = a->y;
        o.length = t.kind.length;
        o.width = t.kind.width;
        o.height = t.kind.height;
        o.heading = a->heading;
        o.vx = static_cast<float>(a->speed * std::cos(a->heading));
        o.vy = static_cast<float>(a->speed * std::sin(a->heading));
        o.valid = true;
      }
      sc.tracks.push_back(std::move(tr));
    }
    choose_tracks_to_predict(&sc);

    const FcdState* centre = e.at(s0 + o_.current_frame);
    sc.map_features = crop_map(map_, {centre->x, centre->y}, o_.map_radius);
    add_signals(s0, &sc);
    cut_.scenarios.push_back(std::move(sc));
  }

  // Up to max_tracks_to_predict agents other than the ego that are valid in every frame, movers first, nearest
  // first: the agents whose futures a prediction benchmark can score.
  void choose_tracks_to_predict(Scenario* sc) const {
    struct Candidate {
      bool still;
      double d2;
      int index;
    };
    std::vector<Candidate> c;
    const ObjectState& ego = sc->tracks[0].states[sc->current_time_index];
    for (size_t i = 1; i < sc->tracks.size(); ++i) {
      const auto& st = sc->tracks[i].states;
      if (!std::all_of(st.begin(), st.end(), [](const ObjectState& s) { return s.valid; })) continue;
      const double moved = std::hypot(st.back().x - st.front().x, st.back().y - st.front().y);
      const ObjectState& now = st[sc->current_time_index];
      c.push_back({moved < 2.0, (now.x - ego.x) * (now.x - ego.x) + (now.y - ego.y) * (now.y - ego.y),
                   static_cast<int>(i)});
    }
    std::sort(c.begin(), c.end(),
              [](const Candidate& a, const Candidate& b) { return std::tie(a.still, a.d2, a.index) < std::tie(b.still, b.d2, b.index); });
    for (size_t k = 0; k < c.size() && static_cast<int>(k) < o_.max_tracks_to_predict; ++k)
      sc->tracks_to_predict.push_back({c[k].index, 0});
  }

  void add_signals(int s0, Scenario* sc) const {
    std::set<int64_t> lanes;
    for (const MapFeature& f : sc->map_features)
      if (f.kind == MapFeatureKind::lane) lanes.insert(f.id);
    sc->signals.assign(o_.frames, {});
    for (int k = 0; k < o_.frames; ++k) {
      const double t = fcd_.time_of(s0 + k);
      std::set<int64_t> done;  // links without an internal lane share their approach lane: its first link speaks
      for (const SignalLink& l : map_.signal_links) {
        if (!lanes.count(l.lane) || done.count(l.lane)) continue;
        const std::string* state = signals_.state_at(l.tl, t);
        if (!state || l.link_index >= static_cast<int>(state->size())) continue;
        done.insert(l.lane);
        sc->signals[k].push_back({l.lane, signal_state_from_sumo((*state)[l.link_index], l.dir), l.stop_point, true});
      }
    }
  }

  const SumoMap& map_;
  const FcdRecording& fcd_;
  const SignalTimeline& signals_;
  const WindowOptions& o_;
  Rng rng_;
  const std::string& prefix_;
  std::vector<std::vector<IncidentFrame>> incidents_;
  WindowCut cut_;
};

}  // namespace

WindowCut cut_windows(const SumoMap& map, const FcdRecording& fcd, const SignalTimeline& signals,
                      const std::vector<Incident>& incidents, const WindowOptions& options, uint64_t seed,
                      const std::string& id_prefix) {
  return Cutter(map, fcd, signals, incidents, options, seed, id_prefix).run();
}

}  // namespace ss
