#include "offline/render/style.h"

#include "absl/strings/str_cat.h"

namespace ss {

const char* agent_colour(ObjectType t) {
  switch (t) {
    case ObjectType::vehicle: return "#2f6fd6";
    case ObjectType::pedestrian: return "#f07d12";
    case ObjectType::cyclist: return "#13a38a";
    case ObjectType::other:
    case ObjectType::unset: break;
  }
  return "#8a5cc2";
}

const char* agent_class(ObjectType t) {
  switch (t) {
    case ObjectType::vehicle: return "vehicle";
    case ObjectType::pedestrian: return "pedestrian";
    case ObjectType::cyclist: return "cyclist";
    case ObjectType::other:
    case ObjectType::unset: break;
  }
  return "other";
}

const char* light_colour(LightState s) {
  switch (s) {
    case LightState::green: return "#1fb141";
    case LightState::yellow: return "#ffc800";
    case LightState::red: return "#e02020";
    case LightState::unknown: break;
  }
  return "#9e9e9e";
}

std::string map_css() {
  std::string css = absl::StrCat(
      ".lane-surface{fill:none;stroke:", colour::kLaneSurface, ";stroke-width:", kLaneSurfaceWidthM,
      ";stroke-linejoin:round;stroke-linecap:round}",
      ".bike-surface{fill:none;stroke:", colour::kBikeLaneSurface, ";stroke-width:", kLaneSurfaceWidthM * 0.6,
      ";stroke-linejoin:round;stroke-linecap:round}",
      ".lane-centre{fill:none;stroke:", colour::kLaneCentre, ";stroke-width:.1;stroke-dasharray:1.5 1.5}",
      ".line{fill:none;stroke-width:", kRoadLineWidthM, "}", ".white{stroke:", colour::kWhiteLine, "}",
      ".yellow{stroke:", colour::kYellowLine, "}", ".dashed{stroke-dasharray:3 5}",
      ".edge{fill:none;stroke:", colour::kRoadEdge, ";stroke-width:.3;stroke-linejoin:round}",
      ".crosswalk{stroke:", colour::kCrosswalk, ";stroke-width:.15}",
      ".bump{fill:", colour::kSpeedBump, ";stroke:#9a5b00;stroke-width:.1}",
      ".driveway{fill:", colour::kDriveway, ";stroke:#a8997c;stroke-width:.15;stroke-dasharray:.8 .8}",
      ".stop-sign{fill:", colour::kStopSign, ";stroke:#fff;stroke-width:.2}",
      ".light{stroke:#1a1a1a;stroke-width:.3}",
      ".trail{fill:none;stroke-width:.35;stroke-opacity:.55;stroke-linejoin:round;stroke-linecap:round}",
      ".agent rect{stroke:#0b1a33;stroke-width:.12;stroke-opacity:.8}",
      ".agent path{fill:#fff;fill-opacity:.9}");
  for (ObjectType t : {ObjectType::vehicle, ObjectType::pedestrian, ObjectType::cyclist, ObjectType::other}) {
    absl::StrAppend(&css, ".agent.", agent_class(t), " rect{fill:", agent_colour(t), "}", ".trail.", agent_class(t),
                    "{stroke:", agent_colour(t), "}");
  }
  absl::StrAppend(&css, ".agent.sdc rect{fill:", colour::kSdc, ";stroke:#111;stroke-width:.3;stroke-opacity:1}",
                  ".trail.sdc{stroke:", colour::kSdc, ";stroke-opacity:.8;stroke-width:.5}", ".halo{fill:none;stroke:",
                  colour::kSdc, ";stroke-width:.5;stroke-opacity:.7}");
  return css;
}

}  // namespace ss
