// The one SVG writer: every SVG the project makes (scene renders, eval's feature histograms, the trainer's loss
// curves) is written with these. Numbers compact (svg_num), text escaped (xml_escape), path data; the plots go
// element by element through SvgWriter. Compact because an animation repeats them per frame.
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

// A document of plain elements (plots): a white page, then elements in drawing order. `attrs` is further attribute
// text written as given (fill="none" stroke="#999"); geometry goes through svg_num, text through xml_escape.
class SvgWriter {
 public:
  SvgWriter(double width, double height, double font_size, std::string_view font_family = "sans-serif");
  SvgWriter& rect(double x, double y, double w, double h, std::string_view attrs);
  SvgWriter& line(double x1, double y1, double x2, double y2, std::string_view attrs);
  SvgWriter& circle(double cx, double cy, double r, std::string_view attrs);
  SvgWriter& path(const std::vector<Vec2>& points, std::string_view attrs);  // an open polyline
  SvgWriter& text(double x, double y, std::string_view text, std::string_view attrs = "");
  // The document, closed. The writer is empty afterwards.
  std::string finish();

 private:
  std::string out_;
};

}  // namespace ss
