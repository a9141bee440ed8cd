#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "offline/render/svg_text.h"
#include "tests/unit/offline/render/xml_dom.h"

namespace ss {
namespace {

using testing::XmlNode;
using testing::XmlReader;

TEST(SvgWriter, WritesAWellFormedDocumentElementByElement) {
  SvgWriter w(640, 360.5, 12);
  w.rect(1, 2.25, 30, 4.126, "fill=\"#9ecae1\"")
      .line(0, 0, 10, -0.004, "stroke=\"black\"")
      .circle(5, 6, 2.5, "fill=\"#ff7f0e\"")
      .path({{0, 0}, {1.5, 2}, {3, 4}}, "fill=\"none\"")
      .path({}, "fill=\"none\"")  // no points, no element
      .text(8, 16, "a < b & \"c\"", "text-anchor=\"end\"");
  const std::string doc = w.finish();
  std::string error;
  auto root = XmlReader::parse(doc, &error);
  ASSERT_TRUE(root) << error << "\n" << doc;
  const XmlNode* svg = root->name == "svg" ? root.get() : root->all("svg").at(0);
  EXPECT_EQ(svg->attr("width"), "640");
  EXPECT_EQ(svg->attr("height"), "360.5");
  EXPECT_EQ(svg->attr("viewBox"), "0 0 640 360.5");
  EXPECT_EQ(svg->attr("font-size"), "12");
  const auto rects = svg->all("rect");
  ASSERT_EQ(rects.size(), 2u);  // the white page, then ours
  EXPECT_EQ(rects[0]->attr("fill"), "white");
  EXPECT_EQ(rects[1]->attr("y"), "2.25");
  EXPECT_EQ(rects[1]->attr("height"), "4.13");  // two decimals, as every number of the SVGs
  EXPECT_EQ(svg->all("line").at(0)->attr("y2"), "0");  // -0.004 rounds to 0, not -0
  EXPECT_EQ(svg->all("path").size(), 1u);
  EXPECT_EQ(svg->all("path").at(0)->attr("d"), "M0 0L1.5 2 3 4");
  EXPECT_EQ(svg->all("text").at(0)->text, "a < b & \"c\"");
  EXPECT_EQ(svg->all("text").at(0)->attr("text-anchor"), "end");
}

TEST(SvgWriter, FinishLeavesTheWriterEmpty) {
  SvgWriter w(10, 10, 11);
  EXPECT_FALSE(w.finish().empty());
  EXPECT_EQ(w.finish(), "</svg>\n");
}

}  // namespace
}  // namespace ss
