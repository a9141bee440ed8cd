// The agents layer: a box per agent with a heading mark and a trail of its recent positions; the SDC on top, haloed.
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "offline/render/layers.h"
#include "offline/render/render.h"
#include "offline/render/style.h"
#include "offline/render/svg_text.h"

namespace ss {
namespace {

// Boxes smaller than this (some sources record pedestrians with no size) would vanish at the default scale.
constexpr double kMinBoxM = 0.5;
// Trail points closer than this are one point, and a trail shorter than kTrailMinLengthM is none: WOMD positions of
// parked cars wander by centimetres, which would draw scribbles (and, animated, rewrite them every frame).
constexpr double kTrailMinStepM = 0.05;
constexpr double kTrailMinLengthM = 0.5;
// An animation draws every second trail point: the trail is rewritten every frame, so this halves most of its bytes.
constexpr int kAnimatedTrailStride = 2;

// The box size drawn in every frame: the current frame's if valid, else the first valid one. WOMD sizes wobble by
// centimetres from frame to frame; a constant box keeps an animation from animating its size.
std::pair<double, double> box_size(const Scenario& s, const Track& t) {
  const ObjectState* st = nullptr;
  if (s.current_time_index < static_cast<int>(t.states.size()) && t.states[s.current_time_index].valid)
    st = &t.states[s.current_time_index];
  for (size_t i = 0; !st && i < t.states.size(); ++i)
    if (t.states[i].valid) st = &t.states[i];
  if (!st) return {kMinBoxM, kMinBoxM};
  return {std::max<double>(st->length, kMinBoxM), std::max<double>(st->width, kMinBoxM)};
}

bool valid_at(const Track& t, int frame) {
  return frame >= 0 && frame < static_cast<int>(t.states.size()) && t.states[frame].valid;
}

// SVG points of the trail ending at `frame`, back over the contiguous valid states; empty when it would not show.
std::vector<Vec2> trail_points(const Scene& scene, const Track& t, int frame, int stride) {
  std::vector<Vec2> pts;
  for (int k = frame; k >= 0 && k >= frame - scene.trail_frames && valid_at(t, k); k -= stride) {
    const Vec2 p = scene.to_svg(t.states[k].x, t.states[k].y);
    if (pts.empty() || distance(pts.back(), p) >= kTrailMinStepM) pts.push_back(p);
  }
  double length = 0;
  for (size_t i = 1; i < pts.size(); ++i) length += distance(pts[i - 1], pts[i]);
  if (pts.size() < 2 || length < kTrailMinLengthM) pts.clear();
  return pts;
}

// Fills holes in a per-frame value list (frames where the agent is absent) with the nearest earlier value, or the
// first value for leading holes: a hidden element then keeps its last value and adds no animation keys.
void fill_holes(std::vector<std::string>& values) {
  auto first = std::find_if(values.begin(), values.end(), [](const std::string& v) { return !v.empty(); });
  if (first == values.end()) return;
  for (auto it = values.begin(); it != first; ++it) *it = *first;
  for (size_t i = 1; i < values.size(); ++i)
    if (values[i].empty()) values[i] = values[i - 1];
}

void draw_agent(const Scene& scene, int track_index, std::string& trails, std::string& boxes) {
  const Scenario& s = scene.scenario;
  const Track& t = s.tracks[track_index];
  const int n = scene.timeline.size();
  const bool sdc = track_index == s.sdc_track_index;
  bool seen = false;
  std::vector<std::string> translate(n), rotate(n), visible(n), trail(n), trail_visible(n);
  for (int i = 0; i < n; ++i) {
    const int frame = scene.timeline.frames()[i];
    const bool valid = valid_at(t, frame);
    visible[i] = valid ? "visible" : "hidden";
    trail_visible[i] = "hidden";
    if (!valid) continue;
    const ObjectState& st = t.states[frame];
    seen = seen || scene.in_view(i, {st.x, st.y}, kViewMarginM);
    const Vec2 p = scene.to_svg(st.x, st.y);
    translate[i] = svg_num(p.x) + " " + svg_num(p.y);
    rotate[i] = svg_num(-st.heading * 180 / kPi, 1);  // y is flipped, so a counter-clockwise heading turns clockwise
    const auto pts = trail_points(scene, t, frame, scene.timeline.animated() ? kAnimatedTrailStride : 1);
    if (!pts.empty()) trail[i] = svg_points(pts), trail_visible[i] = "visible";
  }
  if (!seen) return;
  fill_holes(translate);
  fill_holes(rotate);
  fill_holes(trail);
  const Timeline& tl = scene.timeline;
  const std::string cls = absl::StrCat(agent_class(t.type), sdc ? " sdc" : "");

  if (!trail[0].empty()) {
    absl::StrAppend(&trails, "<polyline class=\"trail ", cls, "\" data-id=\"", t.id, "\" points=\"", trail[0], "\"");
    if (trail_visible[0] == "hidden") trails += " visibility=\"hidden\"";
    const std::string anim = tl.animate("points", trail) + tl.animate("visibility", trail_visible);
    absl::StrAppend(&trails, anim.empty() ? "/>" : ">" + anim + "</polyline>");
  }

  const auto [length, width] = box_size(s, t);
  absl::StrAppend(&boxes, "<g class=\"agent ", cls, "\" data-id=\"", t.id, "\" transform=\"translate(", translate[0],
                  ")\"", visible[0] == "hidden" ? " visibility=\"hidden\"" : "", ">",
                  tl.animate_transform("translate", translate), tl.animate("visibility", visible));
  if (sdc)
    absl::StrAppend(&boxes, "<circle class=\"halo\" r=\"", svg_num(0.5 * std::hypot(length, width) + 1.2), "\"/>");
  // The heading mark: a white wedge at the front of the box.
  const double tip = length / 2, back = tip - std::min(0.4 * length, 0.9 * width), half = 0.32 * width;
  absl::StrAppend(&boxes, "<g transform=\"rotate(", rotate[0], ")\">", tl.animate_transform("rotate", rotate),
                  "<rect x=\"", svg_num(-length / 2), "\" y=\"", svg_num(-width / 2), "\" width=\"", svg_num(length),
                  "\" height=\"", svg_num(width), "\" rx=\"", svg_num(std::min(length, width) * 0.15), "\"/>",
                  "<path d=\"M", svg_num(tip), " 0L", svg_num(back), " ", svg_num(-half), " ", svg_num(back), " ",
                  svg_num(half), "Z\"/></g></g>");
}

}  // namespace

void draw_agents(const Scene& scene, std::string& svg) {
  const Scenario& s = scene.scenario;
  std::string trails, boxes;
  for (int i = 0; i < static_cast<int>(s.tracks.size()); ++i)
    if (i != s.sdc_track_index) draw_agent(scene, i, trails, boxes);
  if (s.sdc_track_index >= 0 && s.sdc_track_index < static_cast<int>(s.tracks.size()))
    draw_agent(scene, s.sdc_track_index, trails, boxes);
  absl::StrAppend(&svg, "<g id=\"trails\">", trails, "</g><g id=\"agents\">", boxes, "</g>");
}

}  // namespace ss
