#include "engine/io/json_text.h"

#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

namespace ss {
namespace {

TEST(JsonText, NonFiniteNumbersAreNullWhereverTheySit) {
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  nlohmann::json j = {{"a", nan}, {"b", {1.5, -inf}}, {"c", {{"d", inf}}}};
  EXPECT_EQ(json_text(j, -1), R"({"a":null,"b":[1.5,null],"c":{"d":null}})");
  EXPECT_EQ(nlohmann::json::parse(json_text(j)), nlohmann::json::parse(R"({"a":null,"b":[1.5,null],"c":{"d":null}})"));
}

TEST(JsonText, InvalidUtf8IsReplacedNotThrown) {
  nlohmann::ordered_json j = {{"id", std::string("ab\xff" "c")}};
  EXPECT_EQ(json_text(j, -1), "{\"id\":\"ab\xef\xbf\xbd" "c\"}");  // U+FFFD
}

TEST(JsonText, OrderedKeysAndIndent) {
  nlohmann::ordered_json j = {{"z", 1}, {"a", "x"}};
  EXPECT_EQ(json_text(j), "{\n  \"z\": 1,\n  \"a\": \"x\"\n}");
  EXPECT_EQ(json_text(j, -1), R"({"z":1,"a":"x"})");
}

}  // namespace
}  // namespace ss
