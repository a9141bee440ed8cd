#include "offline/dataset/xml_scan.h"

#include <gtest/gtest.h>

namespace ss {
namespace {

TEST(XmlScan, TagsAttributesAndSkippedMarkup) {
  const std::string xml =
      "<?xml version=\"1.0\"?>\n"
      "<!-- generated <by> netconvert -->\n"
      "<net version='1.9'>\n"
      "  <edge id=\"a&amp;b\" from=\"J0\" to=\"J1\">text is ignored\n"
      "    <lane id=\"a_0\" speed=\"13.89\" shape=\"0.00,0.00 100.00,0.00\"/>\n"
      "  </edge>\n"
      "  <![CDATA[ <not a tag> ]]>\n"
      "</net>\n";
  XmlScanner x(xml, "t.xml");
  struct Tag {
    std::string name;
    bool start, self_closing;
    int line;
  };
  std::vector<Tag> tags;
  while (true) {
    auto more = x.next();
    ASSERT_TRUE(more.ok()) << more.status();
    if (!*more) break;
    tags.push_back({std::string(x.name()), x.is_start(), x.self_closing(), x.line()});
    if (x.name() == "edge" && x.is_start()) {
      EXPECT_EQ(x.get("id"), "a&b");
      EXPECT_EQ(*x.raw("id"), "a&amp;b");
      EXPECT_FALSE(x.has("function"));
      EXPECT_EQ(x.get("function", "normal"), "normal");
      ASSERT_EQ(x.attributes().size(), 3u);
      EXPECT_EQ(x.attributes()[1].name, "from");
    }
    if (x.name() == "lane") {
      EXPECT_DOUBLE_EQ(*x.number("speed"), 13.89);
      EXPECT_DOUBLE_EQ(*x.number_or("width", 3.2), 3.2);
      EXPECT_FALSE(x.number("id").ok());
      EXPECT_FALSE(x.integer("speed").ok());  // 13.89 is no integer
    }
  }
  ASSERT_EQ(tags.size(), 5u);
  EXPECT_EQ(tags[0].name, "net");
  EXPECT_EQ(tags[0].line, 3);
  EXPECT_EQ(tags[2].name, "lane");
  EXPECT_TRUE(tags[2].self_closing);
  EXPECT_EQ(tags[2].line, 5);
  EXPECT_FALSE(tags[3].start);  // </edge>
  EXPECT_EQ(tags[4].name, "net");
}

TEST(XmlScan, ErrorsNameTheSourceAndLine) {
  for (const std::string bad : {"<a>\n<b x=1/>", "<a>\n<b x=\"1/>", "<a>\n<!-- never closed", "<a>\n<b x>"}) {
    XmlScanner x(bad, "bad.xml");
    absl::Status st;
    while (true) {
      auto more = x.next();
      if (!more.ok()) {
        st = more.status();
        break;
      }
      if (!*more) break;
    }
    EXPECT_FALSE(st.ok()) << bad;
    EXPECT_NE(st.message().find("bad.xml:2"), std::string_view::npos) << st.message();
  }
}

TEST(XmlScan, EntitiesDecodeAndEscapeRoundTrip) {
  EXPECT_EQ(decode_xml_entities("a &lt;b&gt; &quot;c&quot; &apos;d&apos; &#65;&#x42; &unknown; &"),
            "a <b> \"c\" 'd' AB &unknown; &");
  const std::string v = "type=\"peds\" & <x>";
  EXPECT_EQ(decode_xml_entities(escape_xml_attribute(v)), v);
}

}  // namespace
}  // namespace ss
