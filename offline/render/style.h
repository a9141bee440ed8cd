// Colours and line styles of the pictures, shared by the map, the legend and the tests that check them.
#pragma once

#include <string>

#include "engine/scenario/scenario.h"
#include "engine/tokens/light.h"

namespace ss {

namespace colour {
inline constexpr const char* kPage = "#ffffff";
inline constexpr const char* kGround = "#eceae4";       // off-road
inline constexpr const char* kLaneSurface = "#c6c9ce";  // lanes drawn as wide strokes stand in for the road surface
inline constexpr const char* kBikeLaneSurface = "#b9d3b4";
inline constexpr const char* kLaneCentre = "#9aa1ac";
inline constexpr const char* kWhiteLine = "#ffffff";
inline constexpr const char* kYellowLine = "#e5ac00";
inline constexpr const char* kRoadEdge = "#474c54";
inline constexpr const char* kCrosswalk = "#ffffff";
inline constexpr const char* kSpeedBump = "#ec9a1e";
inline constexpr const char* kDriveway = "#d9d0bf";
inline constexpr const char* kStopSign = "#c8102e";
inline constexpr const char* kSdc = "#e0218a";  // magenta: unlike any agent type and any light
inline constexpr const char* kText = "#222222";
}  // namespace colour

// Fill of an agent box by WOMD object type.
const char* agent_colour(ObjectType t);
// Fill of a traffic light in one of the model's 4 states.
const char* light_colour(LightState s);
// CSS class naming an object type ("vehicle", "pedestrian", "cyclist", "other").
const char* agent_class(ObjectType t);

// Widths of map strokes, metres.
inline constexpr double kLaneSurfaceWidthM = 3.8;
inline constexpr double kRoadLineWidthM = 0.15;
inline constexpr double kDoubleLineGapM = 0.13;  // each line of a double line sits this far from the middle
inline constexpr double kLightRadiusM = 1.1;

// The <style> sheet of the map: classes for every map feature, agent type and the SDC.
std::string map_css();

}  // namespace ss
