#include "offline/render/svg_text.h"

#include <cmath>
#include <cstdio>
#include <utility>

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

SvgWriter::SvgWriter(double width, double height, double font_size, std::string_view font_family) {
  const std::string w = svg_num(width), h = svg_num(height);
  out_ = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + w + "\" height=\"" + h + "\" viewBox=\"0 0 " + w + " " +
         h + "\" font-family=\"" + xml_escape(font_family) + "\" font-size=\"" + svg_num(font_size) +
         "\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
}

SvgWriter& SvgWriter::rect(double x, double y, double w, double h, std::string_view attrs) {
  out_ += "<rect x=\"" + svg_num(x) + "\" y=\"" + svg_num(y) + "\" width=\"" + svg_num(w) + "\" height=\"" +
          svg_num(h) + "\" " + std::string(attrs) + "/>\n";
  return *this;
}

SvgWriter& SvgWriter::line(double x1, double y1, double x2, double y2, std::string_view attrs) {
  out_ += "<line x1=\"" + svg_num(x1) + "\" y1=\"" + svg_num(y1) + "\" x2=\"" + svg_num(x2) + "\" y2=\"" +
          svg_num(y2) + "\" " + std::string(attrs) + "/>\n";
  return *this;
}

SvgWriter& SvgWriter::circle(double cx, double cy, double r, std::string_view attrs) {
  out_ += "<circle cx=\"" + svg_num(cx) + "\" cy=\"" + svg_num(cy) + "\" r=\"" + svg_num(r) + "\" " +
          std::string(attrs) + "/>\n";
  return *this;
}

SvgWriter& SvgWriter::path(const std::vector<Vec2>& points, std::string_view attrs) {
  if (points.empty()) return *this;
  out_ += "<path d=\"" + svg_path_data(points, false) + "\" " + std::string(attrs) + "/>\n";
  return *this;
}

SvgWriter& SvgWriter::text(double x, double y, std::string_view text, std::string_view attrs) {
  out_ += "<text x=\"" + svg_num(x) + "\" y=\"" + svg_num(y) + "\"" + (attrs.empty() ? "" : " ") +
          std::string(attrs) + ">" + xml_escape(text) + "</text>\n";
  return *this;
}

std::string SvgWriter::finish() {
  out_ += "</svg>\n";
  std::string doc = std::move(out_);
  out_.clear();
  return doc;
}

}  // namespace ss
