#include "engine/render/svg_text.h"

#include <cmath>
#include <cstdio>

namespace ss {

std::string svg_num(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  std::string s = buf;
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  if (s == "-0") s = "0";
  return s;
}

std::string xml_escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string svg_path_data(const std::vector<Vec2>& points, bool closed) {
  std::string d;
  for (size_t i = 0; i < points.size(); ++i) {
    d += i == 0 ? "M" : i == 1 ? "L" : " ";
    d += svg_num(points[i].x) + " " + svg_num(points[i].y);
  }
  if (closed && !points.empty()) d += "Z";
  return d;
}

std::string svg_points(const std::vector<Vec2>& points) {
  std::string s;
  for (const Vec2& p : points) {
    if (!s.empty()) s += ' ';
    s += svg_num(p.x) + "," + svg_num(p.y);
  }
  return s;
}

}  // namespace ss
