// Pictures of scenes: a scenario (a rollout is one too) as an SVG document, either a still of one frame or a looping
// SMIL animation of every frame. The map is seen from above with north up, around the SDC.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "engine/scenario/scenario.h"

namespace ss {

struct RenderOptions {
  int step = -1;          // the frame of a still; -1: the scenario's current frame
  bool animate = false;   // every frame, as an animation (then step must stay -1)
  double radius_m = 80;   // half the side of the square view
  double trail_s = 2;     // how far back each agent's trail reaches
  int map_px = 900;       // side of the square map area, pixels
};

// Agents and map features up to this far outside the view are still drawn: their boxes and lines may reach into it.
inline constexpr double kViewMarginM = 10;

// The picture. The view is centred on the SDC at each frame drawn (an animation follows it), or, when the scenario
// names no SDC or it is invalid then, on scenario_focus (engine/map/focus.h). The map is a nested <svg id="map"> whose
// viewBox is in metres relative to the view centre at `step` (a still) or to scenario_focus (an animation), so the
// SDC of a still sits at (0, 0); its data-centre-x/y attributes give that centre in world coordinates.
// Errors: a step outside the scenario's frames, a radius that is not positive, a scenario without frames.
absl::StatusOr<std::string> render_scene_svg(const Scenario& scenario, const RenderOptions& options);

}  // namespace ss
