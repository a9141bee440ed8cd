// A pull scanner for the machine-written XML that SUMO reads and writes (networks, FCD, signal switches, collisions):
// start and end tags and their attributes. Text content is skipped (these files carry everything in attributes);
// comments, processing instructions, DOCTYPE and CDATA sections are skipped too. It reads a few hundred MB/s, which
// matters for FCD files of tens of MB per run, and needs no XML library beyond the standard one.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"

namespace ss {

class XmlScanner {
 public:
  // `where` names the source (a file) in error messages. `text` must outlive the scanner.
  XmlScanner(std::string_view text, std::string where);

  // Advances to the next tag: true, or false at the end of the text. An element written as <a/> is reported as a
  // start tag with self_closing() true and no separate end tag. Errors name the source and the line.
  absl::StatusOr<bool> next();

  bool is_start() const { return start_; }
  bool self_closing() const { return self_closing_; }
  std::string_view name() const { return name_; }
  int line() const { return line_; }

  // The attribute's raw value (entities not decoded), or nullopt when the tag has no such attribute.
  std::optional<std::string_view> raw(std::string_view attr) const;
  // The value with the five predefined entities and numeric character references decoded; `fallback` when absent.
  std::string get(std::string_view attr, std::string_view fallback = "") const;
  bool has(std::string_view attr) const { return raw(attr).has_value(); }
  // Numeric attributes: INVALID_ARGUMENT naming the element, attribute and line when absent or not a number.
  absl::StatusOr<double> number(std::string_view attr) const;
  // `fallback` when the attribute is absent; an error when it is present but not a number.
  absl::StatusOr<double> number_or(std::string_view attr, double fallback) const;
  absl::StatusOr<int> integer(std::string_view attr) const;

  // "<where>:<line>: <what>", for callers reporting a semantic error at the current tag.
  std::string location() const;

  struct Attr {
    std::string_view name, value;  // value raw (entities not decoded)
  };
  // Every attribute of the current tag, in document order.
  const std::vector<Attr>& attributes() const { return attrs_; }

 private:
  absl::Status error(std::string_view what) const;
  absl::Status skip_until(std::string_view terminator);
  void count_lines(size_t from, size_t to);

  std::string_view text_;
  std::string where_;
  size_t pos_ = 0;
  size_t lines_counted_to_ = 0;
  int line_ = 1;
  bool start_ = false, self_closing_ = false;
  std::string_view name_;
  std::vector<Attr> attrs_;
};

// Decodes &amp; &lt; &gt; &quot; &apos; and &#N; / &#xN; in an attribute value; other text is copied as is.
std::string decode_xml_entities(std::string_view raw);
// Escapes a value for writing it inside a double-quoted attribute.
std::string escape_xml_attribute(std::string_view value);

}  // namespace ss
