// The one way the project writes JSON: build an nlohmann::json (or ordered_json) value, then turn it into text with
// json_text(). Every writer uses it: the tools' --json outputs (inspect, bench, eval, dataset stats), eval results and
// comparisons, dataset manifests, safetensors headers, the load client's report. Header only (target
// scenestreamer_json), so the C++ clients use it without linking the engine.
//
// The rules, the same for every writer, so the text is always strict JSON (RFC 8259) that any reader accepts:
// - A number that is not finite (NaN, +-infinity) is written as null, never as the invalid tokens NaN or Infinity,
//   and the program goes on: null is "no value" (a metric with nothing to average, a rate over zero agents), which
//   is how the eval results have always said it and what their readers test for. nlohmann-json's serializer does
//   this for every number, wherever it sits in the value; keeping NaN in a value until it is written is fine.
// - A string that is not valid UTF-8 (a file name, a scenario id read from a TFRecord) has each bad byte replaced by
//   U+FFFD instead of throwing (nlohmann-json's default), which would abort the program after its work was done.
#pragma once

#include <string>

#include "nlohmann/json.hpp"

namespace ss {

// `j` as text: `indent` spaces per level with one member or element a line, or everything on one line when it is
// negative. No trailing newline.
template <typename Json>
std::string json_text(const Json& j, int indent = 2) {
  return j.dump(indent, ' ', /*ensure_ascii=*/false, Json::error_handler_t::replace);
}

}  // namespace ss
