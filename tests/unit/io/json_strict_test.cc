#include "engine/io/json_strict.h"

#include <string>

#include <gtest/gtest.h>

namespace ss {
namespace {

std::string error_of(std::string_view text, const JsonLimits& limits = {}) {
  auto j = json_parse_strict(text, limits);
  return j.ok() ? std::string("(parsed)") : std::string(j.status().message());
}

TEST(JsonStrict, ParsesAStrictDocument) {
  auto j = json_parse_strict(R"({"a": [1, 2.5, "x", null, true], "b": {"c": -3}})");
  ASSERT_TRUE(j.ok()) << j.status();
  EXPECT_EQ((*j)["a"].size(), 5u);
  EXPECT_EQ((*j)["b"]["c"].get<int>(), -3);
  EXPECT_DOUBLE_EQ((*j)["a"][1].get<double>(), 2.5);
}

TEST(JsonStrict, DuplicateKeysAreRefusedWithTheirPath) {
  EXPECT_EQ(error_of(R"({"objects": [{"x": 1}, {"x": 1, "x": 2}]})"), "objects[1]: duplicate key \"x\"");
  EXPECT_EQ(error_of(R"({"a": 1, "a": 1})"), "duplicate key \"a\"");
  // A key that is no identifier is written in brackets.
  EXPECT_EQ(error_of(R"({"tl": {"118": {"s": 1, "s": 2}}})"), "tl[\"118\"]: duplicate key \"s\"");
}

TEST(JsonStrict, SyntaxErrorsNameWhereTheyAre) {
  const std::string nan = error_of(R"({"objects": [{"position": [{"x": NaN}]}]})");
  EXPECT_EQ(nan.rfind("objects[0].position[0].x: invalid JSON: ", 0), 0u) << nan;
  EXPECT_NE(error_of(R"({"x": 1e999})").find("x: invalid JSON"), std::string::npos);
  EXPECT_EQ(error_of("").rfind("invalid JSON", 0), 0u);
  EXPECT_NE(error_of("{} x").find("invalid JSON"), std::string::npos);
  // Bytes of the input quoted by the parser come back escaped, not raw.
  EXPECT_EQ(error_of("\xff\xfe").find('\xff'), std::string::npos);
}

TEST(JsonStrict, LimitsOnDepthAndArrayLength) {
  EXPECT_EQ(error_of("[[[1]]]", {.max_depth = 3}), "(parsed)");
  EXPECT_EQ(error_of("[[[[1]]]]", {.max_depth = 3}), "[0][0][0]: nesting deeper than 3 levels");
  EXPECT_EQ(error_of(std::string(100000, '[') + std::string(100000, ']')), "[0][0][0][0][0][0][0][0][0][0][0][0][0][0]"
                                                                          "[0][0][0][0][0][0][0][0][0][0][0][0][0][0]"
                                                                          "[0][0][0][0]: nesting deeper than 32 levels");
  EXPECT_EQ(error_of(R"({"shape": [1, 2, 3]})", {.max_array_length = 3}), "(parsed)");
  EXPECT_EQ(error_of(R"({"shape": [1, 2, 3, 4]})", {.max_array_length = 3}), "shape[3]: an array longer than 3 elements");
  EXPECT_EQ(error_of(R"({"s": [[1], [2]]})", {.max_array_length = 1}), "s[1]: an array longer than 1 elements");
}

TEST(JsonStrict, PrintableEscapesAndCuts) {
  EXPECT_EQ(json_printable("a\nb"), "a\\x0ab");
  EXPECT_EQ(json_printable("\xc3\xa9"), "\xc3\xa9");
  EXPECT_EQ(json_printable("\xc3\xa9", true), "\\xc3\\xa9");
  EXPECT_EQ(json_printable(std::string(70, 'x')), std::string(64, 'x') + "...");
  std::string path;
  json_append_key(path, "objects");
  json_append_key(path, "two words");
  EXPECT_EQ(path, "objects[\"two words\"]");
}

}  // namespace
}  // namespace ss
