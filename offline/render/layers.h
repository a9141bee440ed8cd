// The layers of a picture, drawn in this order: map, lights, trails and agents (the SDC last, on top), then the
// caption and legend outside the map. Internal to offline/render; render.h is the public entry.
#pragma once

#include <string>
#include <vector>

#include "engine/geometry/geometry.h"
#include "offline/render/timeline.h"
#include "engine/scenario/scenario.h"

namespace ss {

// What every layer needs: the scenario, the frames drawn and where the view is at each of them.
struct Scene {
  const Scenario& scenario;
  Timeline timeline;
  Vec2 origin{};             // the world point drawn at SVG (0, 0)
  std::vector<Vec2> centres{};  // world centre of the view at each drawn frame
  double radius_m = 80;      // half the side of the square view
  int trail_frames = 20;     // how many frames back an agent's trail reaches
  double px_per_m = 1;       // map scale, for the legend's scale bar
  double frame_s = 0.1;      // time between frames

  // World -> SVG: relative to the origin, y flipped so that north is up.
  Vec2 to_svg(double x, double y) const { return {x - origin.x, origin.y - y}; }
  // True when a world point lies in the view at drawn frame i, widened by `margin` metres.
  bool in_view(int i, Vec2 p, double margin) const;
  // True when a world box [lo, hi] touches the view at any drawn frame, widened by `margin` metres.
  bool box_in_any_view(Vec2 lo, Vec2 hi, double margin) const;
};

// Lanes, road lines, road edges, crosswalks, speed bumps, driveways, stop signs.
void draw_map(const Scene& scene, std::string& svg);
// Traffic lights at their stop points, coloured by state.
void draw_lights(const Scene& scene, std::string& svg);
// Agent trails, then boxes with a heading mark; the SDC last, with a halo.
void draw_agents(const Scene& scene, std::string& svg);
// Caption above the map at (x, y) px: scenario id, frame and time (one caption per frame when animated).
void draw_caption(const Scene& scene, double x, double y, std::string& svg);
// Legend and scale bar, top-left corner at (x, y) px.
void draw_legend(const Scene& scene, double x, double y, std::string& svg);

}  // namespace ss
