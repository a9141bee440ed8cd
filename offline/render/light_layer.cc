// The lights layer: one disc per signal-controlled lane at its stop point, coloured by the lane's state in the model's
// four colours (engine/tokens/light.h), absent in frames that do not list the lane.
#include <algorithm>
#include <map>
#include <optional>
#include <unordered_map>

#include "absl/strings/str_cat.h"
#include "offline/render/layers.h"
#include "offline/render/render.h"
#include "offline/render/style.h"
#include "offline/render/svg_text.h"
#include "engine/tokens/light.h"

namespace ss {
namespace {

struct Light {
  int64_t lane = 0;
  std::optional<Vec2> position;                      // world; the first stop point seen
  std::vector<std::optional<LightState>> per_frame;  // one per drawn frame; nullopt: not listed then
};

}  // namespace

void draw_lights(const Scene& scene, std::string& svg) {
  const Scenario& s = scene.scenario;
  const int n = scene.timeline.size();
  std::vector<Light> lights;
  std::map<int64_t, size_t> by_lane;
  for (int i = 0; i < n; ++i) {
    const int frame = scene.timeline.frames()[i];
    if (frame >= static_cast<int>(s.signals.size())) continue;
    for (const SignalLaneState& ls : s.signals[frame]) {
      auto [it, added] = by_lane.try_emplace(ls.lane, lights.size());
      if (added) lights.push_back({ls.lane, std::nullopt, std::vector<std::optional<LightState>>(n)});
      Light& l = lights[it->second];
      l.per_frame[i] = light_state_from_womd(ls.state);
      if (!l.position && ls.has_stop_point) l.position = Vec2{ls.stop_point.x, ls.stop_point.y};
    }
  }
  // Without a stop point, the light stands where its lane begins: WOMD's signal-controlled lanes start at the stop
  // line.
  std::unordered_map<int64_t, const MapFeature*> lanes;
  for (const MapFeature& f : s.map_features)
    if (f.kind == MapFeatureKind::lane && !f.points.empty()) lanes.emplace(f.id, &f);
  for (Light& l : lights) {
    auto it = lanes.find(l.lane);
    if (it == lanes.end()) continue;
    const std::vector<MapPoint>& lane = it->second->points;
    if (!l.position) l.position = Vec2{lane[0].x, lane[0].y};
    // A car waiting at the line would cover a disc centred on it, hiding the very state it waits for: the disc goes
    // just past the stop point, along the lane, into the junction.
    size_t k = 0;
    for (size_t j = 1; j < lane.size(); ++j)
      if (distance({lane[j].x, lane[j].y}, *l.position) < distance({lane[k].x, lane[k].y}, *l.position)) k = j;
    const size_t a = k + 1 < lane.size() ? k : (k > 0 ? k - 1 : k), b = std::min(a + 1, lane.size() - 1);
    const Vec2 dir{lane[b].x - lane[a].x, lane[b].y - lane[a].y};
    if (norm(dir) > 1e-6) *l.position = *l.position + (kLightRadiusM + 0.3) / norm(dir) * dir;
  }

  absl::StrAppend(&svg, "<g id=\"lights\">");
  for (const Light& l : lights) {
    if (!l.position || !scene.box_in_any_view(*l.position, *l.position, kViewMarginM)) continue;
    // An absent frame keeps the colour of the nearest listed one (it is hidden anyway), so it adds no fill key.
    std::vector<std::string> fills(n), visibility(n);
    int first = 0;
    while (!l.per_frame[first]) ++first;  // some frame lists the light, or it would not exist
    for (int i = 0; i < n; ++i) {
      fills[i] = l.per_frame[i] ? light_colour(*l.per_frame[i])
                 : i > first     ? fills[i - 1]
                                 : light_colour(*l.per_frame[first]);
      visibility[i] = l.per_frame[i] ? "visible" : "hidden";
    }
    const Vec2 c = scene.to_svg(l.position->x, l.position->y);
    std::string cls = "light";
    if (!scene.timeline.animated() && l.per_frame[0]) absl::StrAppend(&cls, " ", light_state_name(*l.per_frame[0]));
    absl::StrAppend(&svg, "<circle class=\"", cls, "\" data-lane=\"", l.lane, "\" cx=\"", svg_num(c.x), "\" cy=\"",
                    svg_num(c.y), "\" r=\"", svg_num(kLightRadiusM), "\" fill=\"", fills[0], "\"");
    if (visibility[0] == "hidden") svg += " visibility=\"hidden\"";
    const std::string anim = scene.timeline.animate("fill", fills) + scene.timeline.animate("visibility", visibility);
    if (anim.empty()) {
      svg += "/>";
    } else {
      absl::StrAppend(&svg, ">", anim, "</circle>");
    }
  }
  svg += "</g>";
}

}  // namespace ss
