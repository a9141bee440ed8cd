// A strict little XML reader for tests of the SVG pictures: enough of XML 1.0 for what the renderer writes (a
// declaration, comments, elements, double- or single-quoted attributes, text, the five named entities and numeric
// character references). Anything else, and any unbalanced or mismatched tag, is an error, so a parse that succeeds
// means the document is well-formed.
#pragma once

#include <cctype>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace ss::testing {

struct XmlNode {
  std::string name;
  std::map<std::string, std::string> attrs;
  std::vector<std::unique_ptr<XmlNode>> children;
  std::string text;  // all character data directly inside, entities decoded

  std::string attr(const std::string& key) const {
    auto it = attrs.find(key);
    return it == attrs.end() ? "" : it->second;
  }
  // Every descendant (not this node) named `tag`, in document order.
  void find_all(const std::string& tag, std::vector<const XmlNode*>& out) const {
    for (const auto& c : children) {
      if (c->name == tag) out.push_back(c.get());
      c->find_all(tag, out);
    }
  }
  std::vector<const XmlNode*> all(const std::string& tag) const {
    std::vector<const XmlNode*> out;
    find_all(tag, out);
    return out;
  }
  // The first descendant with this id attribute, or null.
  const XmlNode* by_id(const std::string& id) const {
    for (const auto& c : children) {
      if (c->attr("id") == id) return c.get();
      if (const XmlNode* n = c->by_id(id)) return n;
    }
    return nullptr;
  }
  bool has_class(const std::string& cls) const {
    const std::string c = " " + attr("class") + " ";
    return c.find(" " + cls + " ") != std::string::npos;
  }
};

class XmlReader {
 public:
  // The root element, or null with `error` set.
  static std::unique_ptr<XmlNode> parse(const std::string& doc, std::string* error) {
    XmlReader r(doc);
    auto root = r.document();
    if (!root) *error = r.error_ + " at offset " + std::to_string(r.pos_);
    return root;
  }

 private:
  explicit XmlReader(const std::string& doc) : s_(doc) {}

  bool fail(const std::string& why) {
    if (error_.empty()) error_ = why;
    return false;
  }
  bool starts(const char* p) const { return s_.compare(pos_, std::char_traits<char>::length(p), p) == 0; }
  void skip_space() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
  }
  bool skip_past(const char* end) {
    const size_t e = s_.find(end, pos_);
    if (e == std::string::npos) return fail(std::string("unterminated, expected ") + end);
    pos_ = e + std::char_traits<char>::length(end);
    return true;
  }
  bool skip_misc() {  // whitespace, comments, processing instructions
    for (;;) {
      skip_space();
      if (starts("<!--")) {
        if (!skip_past("-->")) return false;
      } else if (starts("<?")) {
        if (!skip_past("?>")) return false;
      } else {
        return true;
      }
    }
  }
  bool name(std::string& out) {
    const size_t b = pos_;
    while (pos_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[pos_])) || s_[pos_] == '-' ||
                                s_[pos_] == '_' || s_[pos_] == ':' || s_[pos_] == '.'))
      ++pos_;
    out = s_.substr(b, pos_ - b);
    if (out.empty() || std::isdigit(static_cast<unsigned char>(out[0])) || out[0] == '-')
      return fail("expected a name");
    return true;
  }
  bool chars(size_t end, std::string& out) {  // character data up to `end`, entities decoded
    while (pos_ < end) {
      const char c = s_[pos_];
      if (c == '<') return fail("'<' in character data");
      if (c != '&') {
        out += c, ++pos_;
        continue;
      }
      const size_t semi = s_.find(';', pos_);
      if (semi == std::string::npos || semi > end) return fail("unterminated entity");
      const std::string ent = s_.substr(pos_ + 1, semi - pos_ - 1);
      static const std::map<std::string, std::string> named = {
          {"amp", "&"}, {"lt", "<"}, {"gt", ">"}, {"quot", "\""}, {"apos", "'"}};
      if (auto it = named.find(ent); it != named.end()) {
        out += it->second;
      } else if (ent.size() > 1 && ent[0] == '#') {
        const bool hex = ent[1] == 'x';
        const std::string digits = ent.substr(hex ? 2 : 1);
        if (digits.empty() || digits.find_first_not_of(hex ? "0123456789abcdefABCDEF" : "0123456789") !=
                                  std::string::npos)
          return fail("bad character reference &" + ent + ";");
        out += '?';  // the tests never look at the character itself
      } else {
        return fail("unknown entity &" + ent + ";");
      }
      pos_ = semi + 1;
    }
    return true;
  }
  std::unique_ptr<XmlNode> element() {
    if (!starts("<")) return fail("expected '<'"), nullptr;
    ++pos_;
    auto node = std::make_unique<XmlNode>();
    if (!name(node->name)) return nullptr;
    for (;;) {
      const size_t before = pos_;
      skip_space();
      if (starts("/>")) {
        pos_ += 2;
        return node;
      }
      if (starts(">")) {
        ++pos_;
        break;
      }
      if (pos_ == before) return fail("expected space between attributes"), nullptr;
      std::string key, value;
      if (!name(key)) return nullptr;
      skip_space();
      if (!starts("=")) return fail("attribute " + key + " without '='"), nullptr;
      ++pos_;
      skip_space();
      if (pos_ >= s_.size() || (s_[pos_] != '"' && s_[pos_] != '\'')) return fail("unquoted attribute " + key), nullptr;
      const char quote = s_[pos_++];
      const size_t close = s_.find(quote, pos_);
      if (close == std::string::npos) return fail("unterminated attribute " + key), nullptr;
      if (!chars(close, value)) return nullptr;
      pos_ = close + 1;
      if (!node->attrs.emplace(key, value).second) return fail("duplicate attribute " + key), nullptr;
    }
    for (;;) {
      if (pos_ >= s_.size()) return fail("unclosed <" + node->name + ">"), nullptr;
      if (starts("</")) {
        pos_ += 2;
        std::string end;
        if (!name(end)) return nullptr;
        if (end != node->name) return fail("</" + end + "> closes <" + node->name + ">"), nullptr;
        skip_space();
        if (!starts(">")) return fail("expected '>'"), nullptr;
        ++pos_;
        return node;
      }
      if (starts("<!--")) {
        if (!skip_past("-->")) return nullptr;
      } else if (starts("<")) {
        auto child = element();
        if (!child) return nullptr;
        node->children.push_back(std::move(child));
      } else {
        size_t lt = s_.find('<', pos_);
        if (lt == std::string::npos) lt = s_.size();
        if (!chars(lt, node->text)) return nullptr;
      }
    }
  }
  std::unique_ptr<XmlNode> document() {
    if (!skip_misc()) return nullptr;
    auto root = element();
    if (!root) return nullptr;
    if (!skip_misc()) return nullptr;
    if (pos_ != s_.size()) return fail("content after the root element"), nullptr;
    return root;
  }

  const std::string& s_;
  size_t pos_ = 0;
  std::string error_;
};

}  // namespace ss::testing
