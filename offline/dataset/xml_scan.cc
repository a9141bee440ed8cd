#include "offline/dataset/xml_scan.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>

#include "absl/strings/str_cat.h"

namespace ss {
namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }
bool is_name_char(char c) {
  return !is_space(c) && c != '=' && c != '>' && c != '/' && c != '<' && c != '"' && c != '\'';
}

void append_utf8(uint32_t cp, std::string* out) {
  if (cp < 0x80) {
    out->push_back(static_cast<char>(cp));
  } else if (cp < 0x800) {
    out->push_back(static_cast<char>(0xC0 | (cp >> 6)));
    out->push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  } else if (cp < 0x10000) {
    out->push_back(static_cast<char>(0xE0 | (cp >> 12)));
    out->push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
    out->push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  } else {
    out->push_back(static_cast<char>(0xF0 | (cp >> 18)));
    out->push_back(static_cast<char>(0x80 | ((cp >> 12) & 0x3F)));
    out->push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
    out->push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  }
}

}  // namespace

std::string decode_xml_entities(std::string_view raw) {
  if (raw.find('&') == std::string_view::npos) return std::string(raw);
  std::string out;
  out.reserve(raw.size());
  for (size_t i = 0; i < raw.size(); ++i) {
    if (raw[i] != '&') {
      out.push_back(raw[i]);
      continue;
    }
    const size_t semi = raw.find(';', i);
    if (semi == std::string_view::npos) {
      out.append(raw.substr(i));
      break;
    }
    const std::string_view ent = raw.substr(i + 1, semi - i - 1);
    if (ent == "amp") out.push_back('&');
    else if (ent == "lt") out.push_back('<');
    else if (ent == "gt") out.push_back('>');
    else if (ent == "quot") out.push_back('"');
    else if (ent == "apos") out.push_back('\'');
    else if (ent.size() > 1 && ent[0] == '#') {
      uint32_t cp = 0;
      const bool hex = ent[1] == 'x' || ent[1] == 'X';
      const std::string_view digits = ent.substr(hex ? 2 : 1);
      auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), cp, hex ? 16 : 10);
      if (ec != std::errc() || p != digits.data() + digits.size() || cp > 0x10FFFF) {
        out.append(raw.substr(i, semi - i + 1));  // not a reference we understand: keep the text
      } else {
        append_utf8(cp, &out);
      }
    } else {
      out.append(raw.substr(i, semi - i + 1));
    }
    i = semi;
  }
  return out;
}

std::string escape_xml_attribute(std::string_view value) {
  std::string out;
  out.reserve(value.size());
  for (char c : value) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out.push_back(c);
    }
  }
  return out;
}

XmlScanner::XmlScanner(std::string_view text, std::string where) : text_(text), where_(std::move(where)) {}

void XmlScanner::count_lines(size_t from, size_t to) {
  line_ += static_cast<int>(std::count(text_.begin() + from, text_.begin() + to, '\n'));
}

std::string XmlScanner::location() const { return absl::StrCat(where_, ":", line_); }

absl::Status XmlScanner::error(std::string_view what) const {
  return absl::InvalidArgumentError(absl::StrCat(location(), ": ", std::string(what)));
}

absl::Status XmlScanner::skip_until(std::string_view terminator) {
  const size_t end = text_.find(terminator, pos_);
  if (end == std::string_view::npos) return error(absl::StrCat("unterminated markup, expected '", std::string(terminator), "'"));
  pos_ = end + terminator.size();
  return absl::OkStatus();
}

absl::StatusOr<bool> XmlScanner::next() {
  while (true) {
    const size_t lt = text_.find('<', pos_);
    if (lt == std::string_view::npos) {
      pos_ = text_.size();
      return false;
    }
    count_lines(lines_counted_to_, lt);
    lines_counted_to_ = lt;
    pos_ = lt + 1;
    const std::string_view rest = text_.substr(pos_);
    if (rest.starts_with("!--")) {
      if (auto st = skip_until("-->"); !st.ok()) return st;
      continue;
    }
    if (rest.starts_with("![CDATA[")) {
      if (auto st = skip_until("]]>"); !st.ok()) return st;
      continue;
    }
    if (rest.starts_with("?") || rest.starts_with("!")) {
      if (auto st = skip_until(">"); !st.ok()) return st;
      continue;
    }
    attrs_.clear();
    self_closing_ = false;
    start_ = true;
    if (rest.starts_with("/")) {
      start_ = false;
      ++pos_;
    }
    const size_t name_begin = pos_;
    while (pos_ < text_.size() && is_name_char(text_[pos_])) ++pos_;
    if (pos_ == name_begin) return error("a tag without a name");
    name_ = text_.substr(name_begin, pos_ - name_begin);
    while (true) {
      while (pos_ < text_.size() && is_space(text_[pos_])) ++pos_;
      if (pos_ >= text_.size()) return error(absl::StrCat("unterminated tag <", std::string(name_)));
      const char c = text_[pos_];
      if (c == '>') {
        ++pos_;
        break;
      }
      if (c == '/') {
        if (pos_ + 1 >= text_.size() || text_[pos_ + 1] != '>' || !start_)
          return error(absl::StrCat("stray '/' in tag <", std::string(name_)));
        self_closing_ = true;
        pos_ += 2;
        break;
      }
      if (!start_) return error(absl::StrCat("attributes in end tag </", std::string(name_)));
      const size_t an = pos_;
      while (pos_ < text_.size() && is_name_char(text_[pos_])) ++pos_;
      if (pos_ == an) return error(absl::StrCat("unexpected '", std::string(1, c), "' in tag <", std::string(name_)));
      const std::string_view attr_name = text_.substr(an, pos_ - an);
      while (pos_ < text_.size() && is_space(text_[pos_])) ++pos_;
      if (pos_ >= text_.size() || text_[pos_] != '=')
        return error(absl::StrCat("attribute ", std::string(attr_name), " of <", std::string(name_), "> has no value"));
      ++pos_;
      while (pos_ < text_.size() && is_space(text_[pos_])) ++pos_;
      if (pos_ >= text_.size() || (text_[pos_] != '"' && text_[pos_] != '\''))
        return error(absl::StrCat("attribute ", std::string(attr_name), " of <", std::string(name_), "> is not quoted"));
      const char quote = text_[pos_++];
      const size_t close = text_.find(quote, pos_);
      if (close == std::string_view::npos)
        return error(absl::StrCat("unterminated value of attribute ", std::string(attr_name)));
      attrs_.push_back({attr_name, text_.substr(pos_, close - pos_)});
      pos_ = close + 1;
    }
    return true;
  }
}

std::optional<std::string_view> XmlScanner::raw(std::string_view attr) const {
  for (const Attr& a : attrs_)
    if (a.name == attr) return a.value;
  return std::nullopt;
}

std::string XmlScanner::get(std::string_view attr, std::string_view fallback) const {
  auto v = raw(attr);
  return v ? decode_xml_entities(*v) : std::string(fallback);
}

absl::StatusOr<double> XmlScanner::number(std::string_view attr) const {
  auto v = raw(attr);
  if (!v) return error(absl::StrCat("<", std::string(name_), "> has no attribute ", std::string(attr)));
  double d = 0;
  auto [p, ec] = std::from_chars(v->data(), v->data() + v->size(), d);
  if (ec != std::errc() || p != v->data() + v->size() || !std::isfinite(d))
    return error(absl::StrCat("<", std::string(name_), "> attribute ", std::string(attr), "=\"", std::string(*v),
                              "\" is not a finite number"));
  return d;
}

absl::StatusOr<double> XmlScanner::number_or(std::string_view attr, double fallback) const {
  if (!has(attr)) return fallback;
  return number(attr);
}

absl::StatusOr<int> XmlScanner::integer(std::string_view attr) const {
  auto v = raw(attr);
  if (!v) return error(absl::StrCat("<", std::string(name_), "> has no attribute ", std::string(attr)));
  int i = 0;
  auto [p, ec] = std::from_chars(v->data(), v->data() + v->size(), i);
  if (ec != std::errc() || p != v->data() + v->size())
    return error(absl::StrCat("<", std::string(name_), "> attribute ", std::string(attr), "=\"", std::string(*v),
                              "\" is not an integer"));
  return i;
}

}  // namespace ss
