#include "offline/render/render.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "engine/map/focus.h"
#include "offline/render/layers.h"
#include "offline/render/style.h"
#include "offline/render/svg_text.h"

namespace ss {

bool Scene::in_view(int i, Vec2 p, double margin) const {
  const double r = radius_m + margin;
  return std::abs(p.x - centres[i].x) <= r && std::abs(p.y - centres[i].y) <= r;
}

bool Scene::box_in_any_view(Vec2 lo, Vec2 hi, double margin) const {
  const double r = radius_m + margin;
  for (const Vec2& c : centres)
    if (hi.x >= c.x - r && lo.x <= c.x + r && hi.y >= c.y - r && lo.y <= c.y + r) return true;
  return false;
}

namespace {

constexpr double kCaptionPx = 44;
constexpr double kLegendPx = 250;
constexpr double kLegendMinHeightPx = 720;  // the legend's rows, so a small map does not cut it off

// Seconds per frame: the median timestamp step (WOMD: 0.1 s); 0.1 s when the timestamps cannot tell.
double frame_seconds(const Scenario& s) {
  std::vector<double> d;
  for (size_t i = 1; i < s.timestamps.size(); ++i)
    if (s.timestamps[i] > s.timestamps[i - 1]) d.push_back(s.timestamps[i] - s.timestamps[i - 1]);
  if (d.empty()) return 0.1;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  // Float timestamps make 0.1 s come out as 0.0999999; a millisecond grid keeps the animation's duration exact.
  return std::max(0.001, std::round(d[d.size() / 2] * 1000) / 1000);
}

// The view centre at each drawn frame: the SDC where it is valid, else where the view last was.
std::vector<Vec2> view_centres(const Scenario& s, const Timeline& tl) {
  const bool has_sdc = s.sdc_track_index >= 0 && s.sdc_track_index < static_cast<int>(s.tracks.size());
  std::vector<Vec2> centres;
  Vec2 last = scenario_focus(s);
  for (int frame : tl.frames()) {
    if (has_sdc) {
      const Track& sdc = s.tracks[s.sdc_track_index];
      if (frame < static_cast<int>(sdc.states.size()) && sdc.states[frame].valid)
        last = {sdc.states[frame].x, sdc.states[frame].y};
    }
    centres.push_back(last);
  }
  return centres;
}

std::string view_box(const Scene& scene, int i) {
  const Vec2 c = scene.to_svg(scene.centres[i].x, scene.centres[i].y);
  const double r = scene.radius_m;
  return absl::StrCat(svg_num(c.x - r), " ", svg_num(c.y - r), " ", svg_num(2 * r), " ", svg_num(2 * r));
}

}  // namespace

absl::StatusOr<std::string> render_scene_svg(const Scenario& s, const RenderOptions& o) {
  const std::string name = absl::StrCat("scenario ", s.id);
  if (s.num_frames() == 0) return absl::InvalidArgumentError(absl::StrCat(name, " has no frames to draw"));
  if (!(o.radius_m > 0) || !std::isfinite(o.radius_m))
    return absl::InvalidArgumentError(absl::StrCat("radius ", o.radius_m, " m: must be a positive number of metres"));
  if (!(o.trail_s >= 0) || !std::isfinite(o.trail_s))
    return absl::InvalidArgumentError(absl::StrCat("trail ", o.trail_s, " s: must be zero or more seconds"));
  if (o.map_px <= 0) return absl::InvalidArgumentError(absl::StrCat("map size ", o.map_px, " px: must be positive"));
  if (o.animate && o.step >= 0)
    return absl::InvalidArgumentError("a step picks the frame of a still; an animation shows every frame");
  if (o.step < -1) return absl::OutOfRangeError(absl::StrCat("step ", o.step, ": frames count from 0"));
  const int step = o.step < 0 ? s.current_time_index : o.step;
  if (!o.animate && (step < 0 || step >= s.num_frames()))
    return absl::OutOfRangeError(
        absl::StrCat("step ", step, " is outside ", name, ", whose frames are 0..", s.num_frames() - 1));

  const double frame_s = frame_seconds(s);
  Scene scene{.scenario = s,
              .timeline = o.animate ? Timeline::animation(s.num_frames(), frame_s) : Timeline::still(step)};
  scene.centres = view_centres(s, scene.timeline);
  scene.origin = o.animate ? scenario_focus(s) : scene.centres[0];
  scene.radius_m = o.radius_m;
  scene.trail_frames = static_cast<int>(std::lround(o.trail_s / frame_s));
  scene.px_per_m = o.map_px / (2 * o.radius_m);
  scene.frame_s = frame_s;

  const double width = o.map_px + kLegendPx, height = std::max(kCaptionPx + o.map_px + 8, kLegendMinHeightPx);
  std::string svg = absl::StrCat(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"", width,
      "\" height=\"", svg_num(height), "\" viewBox=\"0 0 ", width, " ", svg_num(height),
      "\" font-family=\"DejaVu Sans, Helvetica, Arial, sans-serif\">\n<title>", xml_escape(name), "</title>\n<style>",
      map_css(), "</style>\n<rect width=\"100%\" height=\"100%\" fill=\"", colour::kPage, "\"/>\n");
  draw_caption(scene, 10, 28, svg);
  svg += "\n";

  // The map: metres, in a nested viewport that clips whatever lies outside the view.
  const Vec2 centre = scene.origin;
  absl::StrAppend(&svg, "<svg id=\"map\" x=\"0\" y=\"", kCaptionPx, "\" width=\"", o.map_px, "\" height=\"", o.map_px,
                  "\" viewBox=\"", view_box(scene, 0), "\" data-centre-x=\"", svg_num(centre.x), "\" data-centre-y=\"",
                  svg_num(centre.y), "\" data-radius=\"", svg_num(o.radius_m), "\">");
  if (o.animate) {
    std::vector<std::string> boxes;
    for (int i = 0; i < scene.timeline.size(); ++i) boxes.push_back(view_box(scene, i));
    svg += scene.timeline.animate("viewBox", boxes);
  }
  // Ground under every view the animation visits.
  Vec2 lo = scene.to_svg(scene.centres[0].x, scene.centres[0].y), hi = lo;
  for (const Vec2& c : scene.centres) {
    const Vec2 p = scene.to_svg(c.x, c.y);
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y)};
  }
  const double r = o.radius_m + 1;
  absl::StrAppend(&svg, "<rect x=\"", svg_num(lo.x - r), "\" y=\"", svg_num(lo.y - r), "\" width=\"",
                  svg_num(hi.x - lo.x + 2 * r), "\" height=\"", svg_num(hi.y - lo.y + 2 * r), "\" fill=\"",
                  colour::kGround, "\"/>\n");
  draw_map(scene, svg);
  svg += "\n";
  draw_lights(scene, svg);
  svg += "\n";
  draw_agents(scene, svg);
  absl::StrAppend(&svg, "\n</svg>\n<rect x=\".5\" y=\"", svg_num(kCaptionPx + 0.5), "\" width=\"", o.map_px - 1,
                  "\" height=\"", o.map_px - 1, "\" fill=\"none\" stroke=\"#888\"/>\n");
  draw_legend(scene, o.map_px + 20, kCaptionPx - 4, svg);
  svg += "\n</svg>\n";
  return svg;
}

}  // namespace ss
