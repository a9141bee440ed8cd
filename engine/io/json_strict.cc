#include "engine/io/json_strict.h"

#include <algorithm>
#include <cctype>
#include <new>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"

namespace ss {
namespace {

using json = nlohmann::json;

constexpr size_t kMaxQuoted = 64;  // bytes of a user string quoted in an error message

bool is_identifier(std::string_view s) {
  if (s.empty() || std::isdigit(static_cast<unsigned char>(s[0]))) return false;
  return std::all_of(s.begin(), s.end(),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

std::string quote_user(std::string_view s) { return absl::StrCat("\"", json_printable(s), "\""); }

// Builds the DOM from SAX events, which lets it reject duplicate keys and excessive nesting and name the JSON path
// of a syntax error. (nlohmann's callback parser could do the first two, but rescans the parent container at every
// object end: quadratic on large arrays.)
class DomBuilder {
 public:
  DomBuilder(json& root, const JsonLimits& limits) : root_(root), limits_(limits) {}

  bool null() { return put(json(nullptr)); }
  bool boolean(bool v) { return put(json(v)); }
  bool number_integer(json::number_integer_t v) { return put(json(v)); }
  bool number_unsigned(json::number_unsigned_t v) { return put(json(v)); }
  bool number_float(json::number_float_t v, const json::string_t&) { return put(json(v)); }
  bool string(json::string_t& v) { return put(json(std::move(v))); }
  bool binary(json::binary_t&) { return put(json(nullptr)); }  // only binary formats produce these
  bool start_object(std::size_t) { return open(json::value_t::object); }
  bool start_array(std::size_t) { return open(json::value_t::array); }
  bool end_object() { return close(); }
  bool end_array() { return close(); }

  bool key(json::string_t& k) {
    Frame& f = stack_.back();
    f.has_key = false;  // the path of the object itself, for the message below
    if (f.node->contains(k)) {
      error_ = absl::StrCat(path(), path().empty() ? "" : ": ", "duplicate key ", quote_user(k));
      return false;
    }
    f.key = std::move(k);
    f.has_key = true;
    return true;
  }

  bool parse_error(std::size_t, const std::string&, const json::exception& ex) {
    // ex.what() is "[json.exception.parse_error.101] parse error at line 1, column 7: ..."; the tag is noise. The
    // text may quote the offending bytes, which need not be UTF-8.
    std::string_view what = ex.what();
    if (size_t tag = what.find("] "); !what.empty() && what[0] == '[' && tag != std::string_view::npos)
      what.remove_prefix(tag + 2);
    std::string where = path();
    error_ = absl::StrCat(where, where.empty() ? "" : ": ", "invalid JSON: ", printable_all(what));
    return false;
  }

  const std::string& error() const { return error_; }

 private:
  struct Frame {
    json* node;
    std::string key;  // objects: the key whose value is being parsed
    bool has_key = false;
  };

  static std::string printable_all(std::string_view s) {
    std::string out;
    for (size_t i = 0; i < s.size(); i += kMaxQuoted) out += json_printable(s.substr(i, kMaxQuoted), true);
    // json_printable() appends "..." only when it cuts; chunks of exactly kMaxQuoted bytes are never cut.
    return out;
  }

  // The path of the value being parsed, e.g. objects[3].position[12].x.
  std::string path() const {
    std::string out;
    for (size_t i = 0; i < stack_.size(); ++i) {
      const Frame& f = stack_[i];
      if (f.node->is_array()) {
        // An open child container is already the array's last element; otherwise the next element is in progress.
        const bool child_open = i + 1 < stack_.size();
        absl::StrAppend(&out, "[", f.node->size() - (child_open ? 1 : 0), "]");
      } else if (f.has_key) {
        json_append_key(out, f.key);
      }
    }
    return out;
  }

  // Stores a value in the innermost open container (or as the root) and returns its address. Pointers held in
  // stack_ stay valid: only the innermost container grows, and its elements are never on the stack.
  json* place(json&& v) {
    if (stack_.empty()) {
      root_ = std::move(v);
      return &root_;
    }
    Frame& f = stack_.back();
    if (f.node->is_array()) {
      auto& arr = f.node->get_ref<json::array_t&>();
      if (arr.size() >= limits_.max_array_length) {
        error_ = absl::StrCat(path(), ": an array longer than ", limits_.max_array_length, " elements");
        return nullptr;
      }
      arr.push_back(std::move(v));
      return &arr.back();
    }
    json& slot = f.node->get_ref<json::object_t&>()[f.key];
    slot = std::move(v);
    return &slot;
  }

  // A scalar: complete once placed, so the enclosing object's key no longer names the position.
  bool put(json&& v) {
    if (place(std::move(v)) == nullptr) return false;
    if (!stack_.empty()) stack_.back().has_key = false;
    return true;
  }

  bool open(json::value_t t) {
    if (stack_.size() >= limits_.max_depth) {
      error_ = absl::StrCat(path(), ": nesting deeper than ", limits_.max_depth, " levels");
      return false;
    }
    json* node = place(json(t));
    if (node == nullptr) return false;
    stack_.push_back(Frame{node, {}, false});
    return true;
  }

  bool close() {
    stack_.pop_back();
    if (!stack_.empty()) stack_.back().has_key = false;  // the container was the value of that key: complete
    return true;
  }

  json& root_;
  const JsonLimits& limits_;
  std::vector<Frame> stack_;
  std::string error_;
};

}  // namespace

std::string json_printable(std::string_view s, bool escape_non_ascii) {
  std::string out;
  size_t n = s.size();
  bool cut = false;
  if (n > kMaxQuoted) {
    n = kMaxQuoted;
    while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xC0) == 0x80) --n;  // don't split a UTF-8 sequence
    cut = true;
  }
  for (size_t i = 0; i < n; ++i) {
    unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == 0x7F || (escape_non_ascii && c >= 0x80)) {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    } else {
      out += static_cast<char>(c);
    }
  }
  if (cut) out += "...";
  return out;
}

void json_append_key(std::string& out, std::string_view key) {
  if (is_identifier(key)) {
    if (!out.empty()) out += '.';
    out += key;
  } else {
    absl::StrAppend(&out, "[", quote_user(key), "]");
  }
}

absl::StatusOr<json> json_parse_strict(std::string_view text, const JsonLimits& limits) {
  try {
    json root;
    DomBuilder builder(root, limits);
    if (!json::sax_parse(text.data(), text.data() + text.size(), &builder))
      return absl::InvalidArgumentError(builder.error());
    return root;
  } catch (const std::bad_alloc&) {
    // Sizes in the input are bounded by its length, so this means the input is too big for this machine.
    return absl::ResourceExhaustedError(absl::StrCat("out of memory reading ", text.size(), " bytes of JSON"));
  }
}

}  // namespace ss
