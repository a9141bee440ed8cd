#include "engine/scenario/wire_check.h"

#include <cstdint>
#include <limits>
#include <vector>

#include <google/protobuf/descriptor.h>

#include "absl/strings/str_cat.h"

namespace ss {
namespace {

using google::protobuf::Descriptor;
using google::protobuf::EnumDescriptor;
using google::protobuf::FieldDescriptor;
using google::protobuf::FileDescriptor;

enum WireType : int { kVarint = 0, kFixed64 = 1, kLen = 2, kStartGroup = 3, kEndGroup = 4, kFixed32 = 5 };

const char* wire_type_name(int wt) {
  switch (wt) {
    case kVarint: return "varint";
    case kFixed64: return "64-bit";
    case kLen: return "length-delimited";
    case kStartGroup: return "start group";
    case kEndGroup: return "end group";
    case kFixed32: return "32-bit";
    default: return "invalid";
  }
}

int expected_wire_type(const FieldDescriptor& f) {
  switch (f.type()) {
    case FieldDescriptor::TYPE_DOUBLE:
    case FieldDescriptor::TYPE_FIXED64:
    case FieldDescriptor::TYPE_SFIXED64:
      return kFixed64;
    case FieldDescriptor::TYPE_FLOAT:
    case FieldDescriptor::TYPE_FIXED32:
    case FieldDescriptor::TYPE_SFIXED32:
      return kFixed32;
    case FieldDescriptor::TYPE_STRING:
    case FieldDescriptor::TYPE_BYTES:
    case FieldDescriptor::TYPE_MESSAGE:
      return kLen;
    case FieldDescriptor::TYPE_GROUP:
      return kStartGroup;
    default:  // int32, int64, uint32, uint64, sint32, sint64, bool, enum
      return kVarint;
  }
}

// Decodes one varint in [p, end): the number of bytes it takes, 0 if the input ends inside it, -1 if it runs past
// ten bytes or its tenth byte carries bits beyond 64 (libprotobuf would drop them).
int read_varint(const uint8_t* p, const uint8_t* end, uint64_t* value) {
  uint64_t v = 0;
  for (int i = 0; i < 10; ++i) {
    if (p + i >= end) return 0;
    const uint8_t b = p[i];
    if (i == 9 && b > 1) return -1;
    v |= uint64_t{static_cast<uint8_t>(b & 0x7F)} << (7 * i);
    if (!(b & 0x80)) {
      *value = v;
      return i + 1;
    }
  }
  return -1;
}

std::string enum_name(const EnumDescriptor& e) {
  return e.containing_type() ? absl::StrCat(e.containing_type()->name(), ".", e.name()) : e.name();
}

bool fits_int32(uint64_t v) {
  const auto s = static_cast<int64_t>(v);
  return s >= std::numeric_limits<int32_t>::min() && s <= std::numeric_limits<int32_t>::max();
}

class Checker {
 public:
  Checker(std::string_view bytes, const std::string& where)
      : base_(reinterpret_cast<const uint8_t*>(bytes.data())), where_(where) {}

  // Walks [p, end) as one message of type d; `path` names it. With end_group != 0 the message is a group: the walk
  // stops after the END_GROUP tag of that field number and leaves its position in *after.
  absl::Status message(const uint8_t* p, const uint8_t* end, const Descriptor& d, std::string& path, int depth,
                       uint32_t end_group, const uint8_t** after);

 private:
  absl::Status error(const std::string& path, const uint8_t* at, const std::string& what) const {
    return absl::InvalidArgumentError(
        absl::StrCat(where_, ": ", path, ": ", what, " (byte offset ", at - base_, ")"));
  }
  // Reads a length prefix at *p and checks the payload fits before `end`; *p moves past the prefix.
  absl::Status length(const uint8_t** p, const uint8_t* end, const std::string& path, uint64_t* len) const;
  // What is wrong with varint value v for field f, or "" (no allocation on the common path).
  static std::string varint_problem(const FieldDescriptor& f, uint64_t v);
  absl::Status skip_group(const uint8_t** p, const uint8_t* end, uint32_t number, const std::string& path,
                          int depth) const;

  const uint8_t* base_;
  const std::string& where_;
};

absl::Status Checker::length(const uint8_t** p, const uint8_t* end, const std::string& path, uint64_t* len) const {
  const int n = read_varint(*p, end, len);
  if (n == 0) return error(path, *p, "truncated length varint");
  if (n < 0) return error(path, *p, "length varint is longer than 10 bytes or overflows 64 bits");
  const uint64_t left = static_cast<uint64_t>(end - (*p + n));
  if (*len > left)
    return error(path, *p, absl::StrCat("length ", *len, " runs past the end of the enclosing message (", left,
                                        " bytes left)"));
  *p += n;
  return absl::OkStatus();
}

std::string Checker::varint_problem(const FieldDescriptor& f, uint64_t v) {
  switch (f.type()) {
    case FieldDescriptor::TYPE_INT32:
      // Negative int32 values are sign-extended to 64 bits on the wire; anything else would be truncated.
      if (!fits_int32(v)) return absl::StrCat("value ", v, " does not fit int32");
      break;
    case FieldDescriptor::TYPE_UINT32:
    case FieldDescriptor::TYPE_SINT32:
      if (v > std::numeric_limits<uint32_t>::max()) return absl::StrCat("value ", v, " does not fit ", f.type_name());
      break;
    case FieldDescriptor::TYPE_BOOL:
      if (v > 1) return absl::StrCat("value ", v, " is not a bool (0 or 1)");
      break;
    case FieldDescriptor::TYPE_ENUM: {
      const EnumDescriptor& e = *f.enum_type();
      if (!fits_int32(v)) return absl::StrCat("value ", v, " does not fit an enum (int32)");
      // proto2 enums are closed: libprotobuf would move an unknown value to the unknown fields.
      if (e.file()->syntax() != FileDescriptor::SYNTAX_PROTO3 &&
          e.FindValueByNumber(static_cast<int32_t>(static_cast<int64_t>(v))) == nullptr)
        return absl::StrCat("value ", static_cast<int64_t>(v), " is not a known ", enum_name(e), " value");
      break;
    }
    default:
      break;
  }
  return {};
}

absl::Status Checker::skip_group(const uint8_t** pp, const uint8_t* end, uint32_t number, const std::string& path,
                                 int depth) const {
  if (depth > kMaxWireDepth) return error(path, *pp, absl::StrCat("nesting deeper than ", kMaxWireDepth, " levels"));
  const uint8_t* p = *pp;
  while (p < end) {
    const uint8_t* at = p;
    uint64_t tag = 0;
    const int n = read_varint(p, end, &tag);
    if (n <= 0 || tag > std::numeric_limits<uint32_t>::max() || (tag >> 3) == 0)
      return error(path, at, "malformed tag inside an unknown group");
    p += n;
    const auto field = static_cast<uint32_t>(tag >> 3);
    uint64_t v = 0;
    switch (static_cast<int>(tag & 7)) {
      case kVarint: {
        const int m = read_varint(p, end, &v);
        if (m <= 0) return error(path, p, "malformed varint inside an unknown group");
        p += m;
        break;
      }
      case kFixed64:
      case kFixed32: {
        const uint64_t w = (tag & 7) == kFixed64 ? 8 : 4;
        if (static_cast<uint64_t>(end - p) < w) return error(path, p, "truncated fixed-size value in an unknown group");
        p += w;
        break;
      }
      case kLen:
        if (auto st = length(&p, end, path, &v); !st.ok()) return st;
        p += v;
        break;
      case kStartGroup:
        if (auto st = skip_group(&p, end, field, path, depth + 1); !st.ok()) return st;
        break;
      case kEndGroup:
        if (field != number)
          return error(path, at,
                       absl::StrCat("end-group tag for field ", field, " inside the group of field ", number));
        *pp = p;
        return absl::OkStatus();
      default:
        return error(path, at, absl::StrCat("invalid wire type ", tag & 7));
    }
  }
  return error(path, p, absl::StrCat("the group of field ", number, " has no end-group tag"));
}

absl::Status Checker::message(const uint8_t* p, const uint8_t* end, const Descriptor& d, std::string& path,
                              int depth, uint32_t end_group, const uint8_t** after) {
  // Elements seen so far per field (for the [i] in paths), and which member of each oneof is set.
  std::vector<uint64_t> counts(d.field_count(), 0);
  std::vector<const FieldDescriptor*> oneof_set(d.oneof_decl_count(), nullptr);

  while (p < end) {
    const uint8_t* at = p;
    uint64_t tag = 0;
    const int n = read_varint(p, end, &tag);
    if (n == 0) return error(path, at, "truncated tag varint");
    if (n < 0 || tag > std::numeric_limits<uint32_t>::max()) return error(path, at, "tag varint is too large");
    p += n;
    const auto number = static_cast<uint32_t>(tag >> 3);
    const int wt = static_cast<int>(tag & 7);
    if (number == 0) return error(path, at, "field number 0 is invalid");
    if (wt == kEndGroup) {
      if (end_group == number) {
        *after = p;
        return absl::OkStatus();
      }
      return error(path, at, absl::StrCat("unexpected end-group tag for field ", number));
    }
    if (wt > kFixed32) return error(path, at, absl::StrCat("invalid wire type ", wt, " for field ", number));

    const FieldDescriptor* f = d.FindFieldByNumber(static_cast<int>(number));
    if (f == nullptr) {  // unknown: skip it, checking only that it is well-formed
      const std::string upath = absl::StrCat(path, ".<field ", number, ">");
      uint64_t v = 0;
      switch (wt) {
        case kVarint: {
          const int m = read_varint(p, end, &v);
          if (m == 0) return error(upath, p, "truncated varint");
          if (m < 0) return error(upath, p, "varint is longer than 10 bytes or overflows 64 bits");
          p += m;
          break;
        }
        case kFixed64:
        case kFixed32: {
          const uint64_t w = wt == kFixed64 ? 8 : 4;
          if (static_cast<uint64_t>(end - p) < w)
            return error(upath, p, absl::StrCat("truncated ", wire_type_name(wt), " value"));
          p += w;
          break;
        }
        case kLen:
          if (auto st = length(&p, end, upath, &v); !st.ok()) return st;
          p += v;
          break;
        case kStartGroup:
          if (auto st = skip_group(&p, end, number, upath, depth + 1); !st.ok()) return st;
          break;
      }
      continue;
    }

    uint64_t& count = counts[f->index()];
    auto fpath = [&](uint64_t i) {
      return f->is_repeated() ? absl::StrCat(path, ".", f->name(), "[", i, "]") : absl::StrCat(path, ".", f->name());
    };

    if (const auto* oneof = f->real_containing_oneof()) {
      const FieldDescriptor*& set = oneof_set[oneof->index()];
      // libprotobuf would clear the member set first and keep the second.
      if (set != nullptr && set != f)
        return error(fpath(count), at,
                     absl::StrCat("oneof ", oneof->name(), " already holds ", set->name(), " in this message"));
      set = f;
    }

    const int expected = expected_wire_type(*f);
    if (wt == expected) {
      switch (wt) {
        case kVarint: {
          uint64_t v = 0;
          const int m = read_varint(p, end, &v);
          if (m == 0) return error(fpath(count), p, "truncated varint");
          if (m < 0) return error(fpath(count), p, "varint is longer than 10 bytes or overflows 64 bits");
          if (std::string e = varint_problem(*f, v); !e.empty()) return error(fpath(count), p, e);
          p += m;
          break;
        }
        case kFixed64:
        case kFixed32: {
          const uint64_t w = wt == kFixed64 ? 8 : 4;
          if (static_cast<uint64_t>(end - p) < w)
            return error(fpath(count), p,
                         absl::StrCat("truncated ", f->type_name(), ": ", end - p, " of ", w, " bytes left"));
          p += w;
          break;
        }
        case kLen: {
          uint64_t len = 0;
          if (auto st = length(&p, end, fpath(count), &len); !st.ok()) return st;
          if (f->type() == FieldDescriptor::TYPE_MESSAGE) {
            if (depth + 1 > kMaxWireDepth)
              return error(fpath(count), p, absl::StrCat("nesting deeper than ", kMaxWireDepth, " levels"));
            const size_t old = path.size();
            path = fpath(count);
            auto st = message(p, p + len, *f->message_type(), path, depth + 1, 0, nullptr);
            path.resize(old);
            if (!st.ok()) return st;
          } else if (f->type() == FieldDescriptor::TYPE_STRING &&
                     !is_valid_utf8(std::string_view(reinterpret_cast<const char*>(p), len))) {
            return error(fpath(count), p, "string is not valid UTF-8");
          }
          p += len;
          break;
        }
        case kStartGroup: {
          if (depth + 1 > kMaxWireDepth)
            return error(fpath(count), p, absl::StrCat("nesting deeper than ", kMaxWireDepth, " levels"));
          const size_t old = path.size();
          path = fpath(count);
          const uint8_t* next = nullptr;
          auto st = message(p, end, *f->message_type(), path, depth + 1, number, &next);
          path.resize(old);
          if (!st.ok()) return st;
          p = next;
          break;
        }
      }
      ++count;
    } else if (wt == kLen && f->is_packable()) {  // packed repeated scalars
      uint64_t len = 0;
      if (auto st = length(&p, end, fpath(count), &len); !st.ok()) return st;
      const uint8_t* packed_end = p + len;
      if (expected == kVarint) {
        while (p < packed_end) {
          uint64_t v = 0;
          const int m = read_varint(p, packed_end, &v);
          if (m == 0) return error(fpath(count), p, "truncated varint in packed field");
          if (m < 0) return error(fpath(count), p, "varint is longer than 10 bytes or overflows 64 bits");
          if (std::string e = varint_problem(*f, v); !e.empty()) return error(fpath(count), p, e);
          p += m;
          ++count;
        }
      } else {
        const uint64_t w = expected == kFixed64 ? 8 : 4;
        if (len % w != 0)
          return error(fpath(count), p,
                       absl::StrCat("packed length ", len, " is not a multiple of ", w, " for ", f->type_name()));
        count += len / w;
        p = packed_end;
      }
    } else {
      std::string want = absl::StrCat(expected, " (", wire_type_name(expected), ")");
      if (f->is_packable()) absl::StrAppend(&want, " or 2 (length-delimited, packed)");
      std::string type = f->type() == FieldDescriptor::TYPE_MESSAGE
                             ? absl::StrCat("message ", f->message_type()->name())
                             : std::string(f->type_name());
      if (f->is_repeated()) type = absl::StrCat("repeated ", type);
      return error(fpath(count), at,
                   absl::StrCat("wire type ", wt, " (", wire_type_name(wt), "), expected ", want, " for ", type));
    }
  }
  if (end_group != 0) return error(path, p, absl::StrCat("group has no end-group tag"));
  return absl::OkStatus();
}

}  // namespace

bool is_valid_utf8(std::string_view s) {
  const auto* p = reinterpret_cast<const uint8_t*>(s.data());
  const uint8_t* end = p + s.size();
  while (p < end) {
    const uint8_t c = *p;
    if (c < 0x80) {
      ++p;
      continue;
    }
    int n = 0;
    uint32_t cp = 0, min = 0;
    if ((c & 0xE0) == 0xC0) {
      n = 1, cp = c & 0x1F, min = 0x80;
    } else if ((c & 0xF0) == 0xE0) {
      n = 2, cp = c & 0x0F, min = 0x800;
    } else if ((c & 0xF8) == 0xF0) {
      n = 3, cp = c & 0x07, min = 0x10000;
    } else {
      return false;  // a continuation byte without a lead, or 0xF8..0xFF
    }
    if (end - p <= n) return false;
    for (int i = 1; i <= n; ++i) {
      if ((p[i] & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (p[i] & 0x3F);
    }
    if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return false;
    p += n + 1;
  }
  return true;
}

absl::Status check_wire(std::string_view bytes, const Descriptor& d, const std::string& where) {
  Checker checker(bytes, where);
  std::string path = d.name();
  const auto* p = reinterpret_cast<const uint8_t*>(bytes.data());
  return checker.message(p, p + bytes.size(), d, path, 0, 0, nullptr);
}

}  // namespace ss
