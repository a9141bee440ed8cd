// Text of SVG documents: numbers, escaped strings, path data. Kept compact because an animation repeats them per frame.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "engine/geometry/geometry.h"

namespace ss {

// `v` with at most `decimals` decimals and no trailing zeros ("1.5", "-3", "0").
std::string svg_num(double v, int decimals = 2);

// `text` safe inside an XML attribute value or element.
std::string xml_escape(std::string_view text);

// Path data through `points`: "M1 2L3 4 5 6", with "Z" when `closed`. Empty for no points.
std::string svg_path_data(const std::vector<Vec2>& points, bool closed);

// "x,y x,y ..." for a <polyline> or <polygon>.
std::string svg_points(const std::vector<Vec2>& points);

}  // namespace ss
