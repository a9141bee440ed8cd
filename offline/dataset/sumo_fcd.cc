#include "offline/dataset/sumo_fcd.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "absl/strings/str_cat.h"
#include "offline/dataset/xml_scan.h"

namespace ss {

double heading_from_sumo_angle(double angle_degrees) { return wrap_angle((90.0 - angle_degrees) * kPi / 180.0); }

Vec2 centre_from_front(Vec2 front, double heading, double length) {
  return {front.x - 0.5 * length * std::cos(heading), front.y - 0.5 * length * std::sin(heading)};
}

int FcdRecording::frame_of(double t) const { return static_cast<int>(std::lround((t - begin) / step)); }

absl::StatusOr<FcdRecording> parse_fcd(std::string_view xml, const std::string& where, const AgentKinds& kinds,
                                       const AgentTypes& types, double step) {
  FcdRecording rec;
  rec.step = step;
  XmlScanner x(xml, where);
  std::map<std::string, FcdTrack> tracks;
  int frame = -1;
  double first_time = 0;
  while (true) {
    auto more = x.next();
    if (!more.ok()) return more.status();
    if (!*more) break;
    if (!x.is_start()) continue;
    const std::string_view name = x.name();
    if (name == "timestep") {
      auto t = x.number("time");
      if (!t.ok()) return t.status();
      if (frame < 0) {
        first_time = *t;
        frame = 0;
      } else {
        ++frame;
        if (std::abs(*t - (first_time + frame * step)) > 0.25 * step)
          return absl::InvalidArgumentError(absl::StrCat(x.location(), ": timestep ", *t, " is not ", step,
                                                         " s after the previous one"));
      }
      continue;
    }
    const bool person = name == "person";
    if (!person && name != "vehicle") continue;
    if (frame < 0) return absl::InvalidArgumentError(absl::StrCat(x.location(), ": <", std::string(name), "> outside a <timestep>"));
    const std::string id = x.get("id");
    auto it = tracks.find(id);
    if (it == tracks.end()) {
      std::string type = x.get("type");
      if (type.empty()) {
        auto known = types.find(id);
        if (known != types.end()) type = known->second;
      }
      auto k = kinds.find(type);
      if (k == kinds.end())
        return absl::InvalidArgumentError(absl::StrCat(x.location(), ": ", std::string(name), " ", id, " has type \"", type,
                                                       "\", which is not a known vType"));
      FcdTrack t;
      t.id = id;
      t.kind = k->second;
      t.first_frame = frame;
      it = tracks.emplace(id, std::move(t)).first;
    }
    FcdTrack& t = it->second;
    auto px = x.number("x");
    auto py = x.number("y");
    auto angle = x.number("angle");
    auto speed = x.number("speed");
    for (const auto* v : {&px, &py, &angle, &speed})
      if (!v->ok()) return v->status();
    const double h = heading_from_sumo_angle(*angle);
    Vec2 c{*px, *py};
    if (!person) c = centre_from_front(c, h, t.kind.length);
    const int k = frame - t.first_frame;
    if (k < static_cast<int>(t.states.size()))
      return absl::InvalidArgumentError(absl::StrCat(x.location(), ": ", id, " appears twice in one timestep"));
    t.states.resize(k + 1);  // frames it was absent (teleporting) stay invalid
    t.states[k] = {c.x, c.y, static_cast<float>(h), static_cast<float>(*speed), true};
  }
  rec.begin = first_time;
  rec.frames = frame + 1;
  rec.tracks.reserve(tracks.size());
  for (auto& [id, t] : tracks) rec.tracks.push_back(std::move(t));
  return rec;
}

}  // namespace ss
