// Caption and legend: drawn in pixels outside the map, so they stay legible whatever the radius.
#include <cmath>
#include <cstdio>

#include "absl/strings/str_cat.h"
#include "offline/render/layers.h"
#include "offline/render/style.h"
#include "offline/render/svg_text.h"

namespace ss {
namespace {

// One decimal, always shown: a caption that changes width from "1 s" to "1.5 s" jitters in an animation.
std::string fixed_1(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

std::string caption_text(const Scenario& s, int frame) {
  const double t = frame < static_cast<int>(s.timestamps.size()) ? s.timestamps[frame] : 0;
  return absl::StrCat("scenario ", xml_escape(s.id), "  \xc2\xb7  frame ", frame, "/", s.num_frames() - 1,
                      "  \xc2\xb7  t = ", fixed_1(t), " s  \xc2\xb7  current frame ", s.current_time_index);
}

// The longest 1, 2 or 5 x 10^k metres not over a quarter of the radius.
double scale_bar_m(double radius_m) {
  const double target = radius_m / 4, decade = std::pow(10.0, std::floor(std::log10(target)));
  for (double m : {5.0, 2.0, 1.0})
    if (m * decade <= target) return m * decade;
  return decade;
}

class Legend {
 public:
  Legend(double x, double y, std::string& svg) : x_(x), y_(y), svg_(svg) {}

  void heading(const std::string& text) {
    y_ += 8;
    text_at(x_, y_ + 13, text, " font-weight=\"bold\"");
    y_ += 20;
  }
  // A row: `swatch`, drawn in a 30x14 px box, then the label.
  void row(const std::string& label, const std::string& swatch) {
    absl::StrAppend(&svg_, "<g transform=\"translate(", svg_num(x_), " ", svg_num(y_ + 2), ")\">", swatch, "</g>");
    text_at(x_ + 40, y_ + 13, label, "");
    y_ += 19;
  }
  double y() const { return y_; }
  void skip(double dy) { y_ += dy; }

 private:
  void text_at(double x, double y, const std::string& text, const char* extra) {
    absl::StrAppend(&svg_, "<text x=\"", svg_num(x), "\" y=\"", svg_num(y), "\"", extra, ">", xml_escape(text),
                    "</text>");
  }
  double x_, y_;
  std::string& svg_;
};

std::string box_swatch(const char* fill, const char* stroke, double stroke_width) {
  return absl::StrCat("<rect x=\"3\" y=\"2\" width=\"24\" height=\"10\" rx=\"2\" fill=\"", fill, "\" stroke=\"",
                      stroke, "\" stroke-width=\"", svg_num(stroke_width), "\"/><path d=\"M27 7L20 3.8 20 10.2Z\" ",
                      "fill=\"#fff\"/>");
}

std::string line_swatch(const char* colour, double width, const char* dash, const char* under = nullptr) {
  std::string s;
  if (under) absl::StrAppend(&s, "<rect width=\"30\" height=\"14\" fill=\"", under, "\"/>");
  absl::StrAppend(&s, "<path d=\"M0 7H30\" stroke=\"", colour, "\" stroke-width=\"", svg_num(width), "\"",
                  dash ? absl::StrCat(" stroke-dasharray=\"", dash, "\"") : "", "/>");
  return s;
}

std::string disc_swatch(const char* fill) {
  return absl::StrCat("<circle cx=\"15\" cy=\"7\" r=\"6\" fill=\"", fill,
                      "\" stroke=\"#1a1a1a\" stroke-width=\"1.5\"/>");
}

}  // namespace

void draw_caption(const Scene& scene, double x, double y, std::string& svg) {
  const Timeline& tl = scene.timeline;
  absl::StrAppend(&svg, "<g id=\"caption\" font-size=\"16\" fill=\"", colour::kText, "\">");
  for (int i = 0; i < tl.size(); ++i) {
    absl::StrAppend(&svg, "<text x=\"", svg_num(x), "\" y=\"", svg_num(y), "\"");
    if (tl.animated()) {
      // Shown during drawn frame i only.
      std::vector<std::string> vis(tl.size(), "hidden");
      vis[i] = "visible";
      if (i > 0) svg += " visibility=\"hidden\"";
      absl::StrAppend(&svg, ">", tl.animate("visibility", vis));
    } else {
      svg += ">";
    }
    absl::StrAppend(&svg, caption_text(scene.scenario, tl.frames()[i]), "</text>");
  }
  svg += "</g>";
}

void draw_legend(const Scene& scene, double x, double y, std::string& svg) {
  absl::StrAppend(&svg, "<g id=\"legend\" font-size=\"13\" fill=\"", colour::kText, "\">");
  Legend l(x, y, svg);
  l.heading("Agents");
  for (ObjectType t : {ObjectType::vehicle, ObjectType::pedestrian, ObjectType::cyclist, ObjectType::other})
    l.row(agent_class(t), box_swatch(agent_colour(t), "#0b1a33", 0.8));
  l.row("SDC (controlled)", absl::StrCat("<circle cx=\"15\" cy=\"7\" r=\"13\" fill=\"none\" stroke=\"", colour::kSdc,
                                         "\" stroke-opacity=\".7\" stroke-width=\"2\"/>",
                                         box_swatch(colour::kSdc, "#111", 1.5)));
  l.row(absl::StrCat("trail (last ", svg_num(scene.trail_frames * scene.frame_s, 1), " s)"),
        line_swatch(agent_colour(ObjectType::vehicle), 2.5, nullptr));
  l.heading("Traffic lights");
  for (LightState s : {LightState::green, LightState::yellow, LightState::red, LightState::unknown})
    l.row(light_state_name(s), disc_swatch(light_colour(s)));
  l.heading("Map");
  l.row("lane", absl::StrCat(line_swatch(colour::kLaneSurface, 12, nullptr),
                             line_swatch(colour::kLaneCentre, 1, "4 4")));
  l.row("bike lane", line_swatch(colour::kBikeLaneSurface, 8, nullptr));
  l.row("white line, broken", line_swatch(colour::kWhiteLine, 2, "8 6", colour::kLaneSurface));
  l.row("white line, solid", line_swatch(colour::kWhiteLine, 2, nullptr, colour::kLaneSurface));
  l.row("yellow line, broken", line_swatch(colour::kYellowLine, 2, "8 6", colour::kLaneSurface));
  l.row("yellow line, solid", line_swatch(colour::kYellowLine, 2, nullptr, colour::kLaneSurface));
  l.row("double yellow", absl::StrCat("<rect width=\"30\" height=\"14\" fill=\"", colour::kLaneSurface, "\"/>",
                                      "<path d=\"M0 5H30M0 9H30\" stroke=\"", colour::kYellowLine,
                                      "\" stroke-width=\"2\"/>"));
  l.row("road edge", line_swatch(colour::kRoadEdge, 3, nullptr));
  l.row("crosswalk", absl::StrCat("<rect width=\"30\" height=\"14\" fill=\"", colour::kLaneSurface,
                                  "\"/><path d=\"M3 0V14M9 0V14M15 0V14M21 0V14M27 0V14\" stroke=\"",
                                  colour::kCrosswalk, "\" stroke-width=\"3\"/>"));
  l.row("speed bump", absl::StrCat("<rect x=\"2\" y=\"3\" width=\"26\" height=\"8\" fill=\"", colour::kSpeedBump,
                                   "\" stroke=\"#9a5b00\"/>"));
  l.row("driveway", absl::StrCat("<rect x=\"2\" y=\"1\" width=\"26\" height=\"12\" fill=\"", colour::kDriveway,
                                 "\" stroke=\"#a8997c\" stroke-dasharray=\"3 3\"/>"));
  l.row("stop sign", absl::StrCat("<polygon points=\"12,1 18,1 22,5 22,9 18,13 12,13 8,9 8,5\" fill=\"",
                                  colour::kStopSign, "\" stroke=\"#fff\"/>"));
  // Scale bar and orientation.
  l.skip(14);
  const double bar_m = scale_bar_m(scene.radius_m), bar_px = bar_m * scene.px_per_m;
  absl::StrAppend(&svg, "<path d=\"M", svg_num(x), " ", svg_num(l.y()), "v6h", svg_num(bar_px), "v-6\" fill=\"none\" ",
                  "stroke=\"", colour::kText, "\" stroke-width=\"1.5\"/>", "<text x=\"", svg_num(x + bar_px + 8),
                  "\" y=\"", svg_num(l.y() + 8), "\">", svg_num(bar_m), " m</text>");
  l.skip(30);
  absl::StrAppend(&svg, "<text x=\"", svg_num(x), "\" y=\"", svg_num(l.y()), "\">north up (y axis flipped)</text>");
  svg += "</g>";
}

}  // namespace ss
