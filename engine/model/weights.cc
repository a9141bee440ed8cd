#include "engine/model/weights.h"

#include <algorithm>
#include <bit>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "engine/base/rng.h"
#include "engine/io/file_io.h"
#include "engine/io/json_strict.h"
#include "engine/io/json_text.h"

namespace ss {
namespace {

using json = nlohmann::json;

constexpr uint64_t kHeaderLengthBytes = 8;
constexpr size_t kMaxHeaderDepth = 8;       // a real header nests 3 deep: root, tensor entry, shape
constexpr size_t kMaxHeaderArrayLength = 64;  // arrays are shapes (rank) and data_offsets (2)
constexpr double kInitStd = 0.02;

// ---------------------------------------------------------------------------------------------------------------
// Deterministic random init.

// N(0, std) by Box-Muller, computed in double and rounded to float. No expression has the a * b + c form, so FMA
// contraction cannot change results between compilers; the remaining dependence is libm's log/sin/cos, whose
// last-ulp differences in double almost never survive the rounding to float.
void fill_normal(std::vector<float>& out, uint64_t stream_seed, double std_dev) {
  Rng rng(stream_seed);
  constexpr double kTwoPi = 6.283185307179586476925286766559;
  for (size_t i = 0; i < out.size(); i += 2) {
    const double u1 = static_cast<double>((rng.next() >> 11) + 1) * 0x1p-53;  // (0, 1]: log(u1) is finite
    const double u2 = static_cast<double>(rng.next() >> 11) * 0x1p-53;        // [0, 1)
    const double r = std_dev * std::sqrt(-2.0 * std::log(u1));
    const double theta = kTwoPi * u2;
    out[i] = static_cast<float>(r * std::cos(theta));
    if (i + 1 < out.size()) out[i + 1] = static_cast<float>(r * std::sin(theta));
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Messages.

// Text from a file, made safe to print: non-printable bytes escaped, long text cut.
std::string printable(std::string_view s, size_t max_len = 100) {
  std::string out;
  for (size_t i = 0; i < s.size() && i < max_len; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7F && c != '\\')
      out += static_cast<char>(c);
    else
      out += absl::StrFormat("\\x%02x", c);
  }
  if (s.size() > max_len) out += "...";
  return out;
}

absl::Status bad(const std::string& where, const std::string& what) {
  return absl::InvalidArgumentError(absl::StrCat(where, ": ", what));
}

absl::Status bad_tensor(const std::string& where, std::string_view name, const std::string& what) {
  return bad(where, absl::StrCat("tensor '", printable(name), "': ", what));
}

template <typename T>
std::string format_shape(const std::vector<T>& shape) {
  return absl::StrCat("[", absl::StrJoin(shape, ", "), "]");
}

int64_t element_count(const std::vector<int64_t>& shape) {
  int64_t n = 1;
  for (int64_t d : shape) n *= d;
  return n;
}

absl::Status check_finite(const std::string& where, const std::string& name, const std::vector<float>& data) {
  for (size_t i = 0; i < data.size(); ++i)
    if (!std::isfinite(data[i]))
      return bad_tensor(where, name, absl::StrCat("value at flat index ", i, " is ", std::isnan(data[i]) ? "NaN" : "infinite"));
  return absl::OkStatus();
}

// validate_config plus what model_parameter_specs needs to compute shapes without overflowing int (ffn_dim()).
absl::Status check_config(const ModelConfig& c, const std::string& where) {
  if (auto st = validate_config(c); !st.ok()) return bad(where, std::string(st.message()));
  if (int64_t{c.ffn_mult} * c.d_model > INT_MAX)
    return bad(where, absl::StrCat("model config ffn_mult ", c.ffn_mult, " * d_model ", c.d_model, " is out of range"));
  return absl::OkStatus();
}

// ---------------------------------------------------------------------------------------------------------------
// Header JSON.

// A JSON array of at most `max_count` non-negative integers.
bool read_uints(const json& j, size_t max_count, std::vector<uint64_t>* out) {
  if (!j.is_array() || j.size() > max_count) return false;
  out->clear();
  for (const json& v : j) {
    if (v.is_number_unsigned())
      out->push_back(v.get<uint64_t>());
    else if (v.is_number_integer() && v.get<int64_t>() >= 0)
      out->push_back(static_cast<uint64_t>(v.get<int64_t>()));
    else
      return false;
  }
  return true;
}

uint64_t load_le64(const char* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = v << 8 | static_cast<unsigned char>(p[i]);
  return v;
}

void append_le64(std::string& out, uint64_t v) {
  for (int i = 0; i < 8; ++i) out += static_cast<char>(v >> (8 * i) & 0xFF);
}

// The file stores little-endian floats; on a little-endian host (every target today) that is a plain copy.
void decode_f32(const char* src, std::vector<float>& out) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(out.data(), src, out.size() * sizeof(float));
  } else {
    for (size_t i = 0; i < out.size(); ++i) {
      uint32_t u = 0;
      for (int b = 3; b >= 0; --b) u = u << 8 | static_cast<unsigned char>(src[4 * i + b]);
      out[i] = std::bit_cast<float>(u);
    }
  }
}

void append_f32(std::string& out, const std::vector<float>& data) {
  if constexpr (std::endian::native == std::endian::little) {
    out.append(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(float));
  } else {
    for (float f : data) {
      const uint32_t u = std::bit_cast<uint32_t>(f);
      for (int b = 0; b < 4; ++b) out += static_cast<char>(u >> (8 * b) & 0xFF);
    }
  }
}

// One tensor's bytes in the data section, for the layout check.
struct Extent {
  uint64_t begin, end;
  const std::string* name;
};

// The tensors must tile the data section exactly, as the reference safetensors implementation requires: an overlap
// means two tensors share bytes, a gap or tail means bytes nobody reads (a sign of a corrupt or mis-written file).
absl::Status check_layout(std::vector<Extent> extents, uint64_t data_size, const std::string& where) {
  std::sort(extents.begin(), extents.end(),
            [](const Extent& a, const Extent& b) { return a.begin != b.begin ? a.begin < b.begin : a.end < b.end; });
  // Overlaps first: moving one tensor onto another also leaves a gap, and the overlap is the better explanation.
  const Extent* furthest = nullptr;  // the extent reaching furthest so far
  for (const Extent& e : extents) {
    if (furthest != nullptr && e.begin < furthest->end)
      return bad(where, absl::StrCat("tensors '", printable(*furthest->name), "' (bytes ", furthest->begin, "..",
                                     furthest->end, ") and '", printable(*e.name), "' (bytes ", e.begin, "..", e.end,
                                     ") overlap in the data section"));
    if (furthest == nullptr || e.end > furthest->end) furthest = &e;
  }
  uint64_t pos = 0;
  const Extent* prev = nullptr;
  for (const Extent& e : extents) {
    if (e.begin > pos)
      return bad_tensor(where, *e.name,
                        absl::StrCat("bytes ", pos, "..", e.begin, " of the data section before it belong to no tensor"));
    pos = e.end;
    prev = &e;
  }
  if (pos != data_size)
    return bad(where, absl::StrCat("the data section has ", data_size - pos, " bytes after the last tensor",
                                   prev ? absl::StrCat(" ('", printable(*prev->name), "')") : ""));
  return absl::OkStatus();
}

absl::StatusOr<Weights> parse_weights_impl(std::string_view bytes, const std::string& where) {
  if (bytes.size() < kHeaderLengthBytes)
    return bad(where, absl::StrCat("the file is ", bytes.size(), " bytes, too short for the 8-byte header length"));
  const uint64_t header_size = load_le64(bytes.data());
  if (header_size > kMaxWeightsHeaderBytes)
    return bad(where, absl::StrCat("header length ", header_size, " exceeds the limit of ", kMaxWeightsHeaderBytes,
                                   " bytes (100 MB): not a weight file"));
  if (header_size > bytes.size() - kHeaderLengthBytes)
    return bad(where, absl::StrCat("header length ", header_size, " exceeds the ", bytes.size() - kHeaderLengthBytes,
                                   " bytes after it: the file is truncated or not a weight file"));
  const std::string_view text = bytes.substr(kHeaderLengthBytes, header_size);
  const std::string_view data = bytes.substr(kHeaderLengthBytes + header_size);

  auto parsed = json_parse_strict(text, {.max_depth = kMaxHeaderDepth, .max_array_length = kMaxHeaderArrayLength});
  if (!parsed.ok()) return absl::Status(parsed.status().code(), absl::StrCat(where, ": invalid JSON header: ",
                                                                           parsed.status().message()));
  const json& header = *parsed;
  if (!header.is_object()) return bad(where, "the header is not a JSON object");

  // The configuration first: it says which tensors the file must hold.
  const auto meta_it = header.find("__metadata__");
  if (meta_it == header.end()) return bad(where, "the header has no __metadata__ (the model configuration)");
  if (!meta_it->is_object()) return bad(where, "__metadata__ is not an object");
  std::map<std::string, std::string> meta;
  for (auto it = meta_it->begin(); it != meta_it->end(); ++it) {
    if (!it.value().is_string())
      return bad(where, absl::StrCat("__metadata__ '", printable(it.key()), "' is not a string"));
    meta[it.key()] = it.value().get<std::string>();
  }
  auto config = config_from_metadata(meta);
  if (!config.ok()) return bad(where, std::string(config.status().message()));
  if (auto st = check_config(*config, where); !st.ok()) return st;

  const std::vector<TensorSpec> specs = model_parameter_specs(*config);
  std::map<std::string_view, const TensorSpec*> spec_by_name;
  for (const TensorSpec& s : specs) spec_by_name[s.name] = &s;

  Weights w;
  w.config = *config;
  std::vector<Extent> extents;
  std::vector<uint64_t> dims;
  for (auto it = header.begin(); it != header.end(); ++it) {
    const std::string& name = it.key();
    if (name == "__metadata__") continue;
    const auto spec_it = spec_by_name.find(name);
    if (spec_it == spec_by_name.end())
      return bad_tensor(where, name,
                        absl::StrCat("unexpected: not a parameter of the '", printable(config->name), "' configuration"));
    const TensorSpec& spec = *spec_it->second;
    const json& entry = it.value();
    if (!entry.is_object()) return bad_tensor(where, name, "its header entry is not an object");

    const auto dtype = entry.find("dtype");
    if (dtype == entry.end() || !dtype->is_string()) return bad_tensor(where, name, "no dtype string");
    if (dtype->get_ref<const std::string&>() != "F32")
      return bad_tensor(where, name,
                        absl::StrCat("dtype ", printable(dtype->get_ref<const std::string&>()), ", expected F32"));

    const auto shape = entry.find("shape");
    if (shape == entry.end() || !read_uints(*shape, kMaxHeaderArrayLength, &dims))
      return bad_tensor(where, name, "shape is missing or not a list of non-negative integers");
    if (!std::equal(dims.begin(), dims.end(), spec.shape.begin(), spec.shape.end(),
                    [](uint64_t got, int64_t want) { return got == static_cast<uint64_t>(want); }))
      return bad_tensor(where, name,
                        absl::StrCat("shape differs from the configuration: expected ", format_shape(spec.shape),
                                     ", got ", format_shape(dims)));

    const auto offsets = entry.find("data_offsets");
    if (offsets == entry.end() || !read_uints(*offsets, 2, &dims) || dims.size() != 2)
      return bad_tensor(where, name, "data_offsets is missing or not a pair of non-negative integers [begin, end]");
    const uint64_t begin = dims[0], end = dims[1];
    if (begin > end || end > data.size())
      return bad_tensor(where, name,
                        absl::StrCat("data_offsets [", begin, ", ", end, "] are out of bounds: the data section has ",
                                     data.size(), " bytes"));
    // The shape equals the spec's, whose element count is bounded (check_config), so this cannot overflow.
    const int64_t count = element_count(spec.shape);
    const uint64_t need = static_cast<uint64_t>(count) * sizeof(float);
    if (end - begin != need)
      return bad_tensor(where, name,
                        absl::StrCat("data_offsets [", begin, ", ", end, "] span ", end - begin, " bytes, but shape ",
                                     format_shape(spec.shape), " of F32 needs ", need));
    extents.push_back({begin, end, &name});

    Tensor t;
    t.shape = spec.shape;
    t.data.resize(static_cast<size_t>(count));
    decode_f32(data.data() + begin, t.data);
    if (auto st = check_finite(where, name, t.data); !st.ok()) return st;
    w.tensors.emplace(name, std::move(t));
  }

  // Every present tensor is a spec name (checked above), so any missing spec means the file is incomplete.
  const TensorSpec* first = nullptr;
  size_t missing = 0;
  for (const TensorSpec& s : specs)
    if (!w.tensors.count(s.name) && missing++ == 0) first = &s;
  if (first != nullptr) {
    return bad_tensor(where, first->name,
                      absl::StrCat("missing", missing > 1 ? absl::StrCat(" (and ", missing - 1, " more)") : "",
                                   "; the '", printable(config->name), "' configuration has ", specs.size(),
                                   " tensors"));
  }
  if (auto st = check_layout(std::move(extents), data.size(), where); !st.ok()) return st;
  return w;
}

}  // namespace

const Tensor& Weights::at(const std::string& name) const {
  const auto it = tensors.find(name);
  if (it == tensors.end()) {
    std::fprintf(stderr, "ss::Weights::at: no tensor '%s' (a programming error: the loader checks every parameter)\n",
                 name.c_str());
    std::abort();
  }
  return it->second;
}

int64_t Weights::parameter_count() const {
  int64_t n = 0;
  for (const auto& [name, t] : tensors) n += static_cast<int64_t>(t.data.size());
  return n;
}

Weights init_weights(const ModelConfig& config, uint64_t seed) {
  Weights w;
  w.config = config;
  // Each tensor draws from its own stream keyed by (seed, name), so adding or reordering parameters leaves the
  // others' values unchanged.
  const uint64_t mixed_seed = mix_seed(seed);
  for (const TensorSpec& spec : model_parameter_specs(config)) {
    Tensor t;
    t.shape = spec.shape;
    t.data.assign(static_cast<size_t>(element_count(spec.shape)), 0.0f);
    switch (spec.init) {
      case TensorSpec::Init::normal:
        fill_normal(t.data, mixed_seed ^ fnv1a64(spec.name), kInitStd);
        break;
      case TensorSpec::Init::ones:
        std::fill(t.data.begin(), t.data.end(), 1.0f);
        break;
      case TensorSpec::Init::zeros:
        break;
    }
    w.tensors.emplace(spec.name, std::move(t));
  }
  return w;
}

absl::Status validate_weights(const Weights& w, const std::string& where) {
  if (auto st = check_config(w.config, where); !st.ok()) return st;
  const std::vector<TensorSpec> specs = model_parameter_specs(w.config);
  std::map<std::string_view, const TensorSpec*> spec_by_name;
  for (const TensorSpec& s : specs) spec_by_name[s.name] = &s;
  for (const auto& [name, t] : w.tensors)
    if (!spec_by_name.count(name))
      return bad_tensor(where, name,
                        absl::StrCat("unexpected: not a parameter of the '", printable(w.config.name), "' configuration"));
  for (const TensorSpec& spec : specs) {
    const auto it = w.tensors.find(spec.name);
    if (it == w.tensors.end()) return bad_tensor(where, spec.name, "missing");
    const Tensor& t = it->second;
    if (t.shape != spec.shape)
      return bad_tensor(where, spec.name,
                        absl::StrCat("shape differs from the configuration: expected ", format_shape(spec.shape),
                                     ", got ", format_shape(t.shape)));
    if (t.data.size() != static_cast<size_t>(element_count(spec.shape)))
      return bad_tensor(where, spec.name,
                        absl::StrCat("holds ", t.data.size(), " values, but shape ", format_shape(spec.shape), " has ",
                                     element_count(spec.shape)));
    if (auto st = check_finite(where, spec.name, t.data); !st.ok()) return st;
  }
  return absl::OkStatus();
}

absl::StatusOr<Weights> parse_weights(std::string_view bytes, const std::string& where) {
  try {
    return parse_weights_impl(bytes, where);
  } catch (const std::bad_alloc&) {
    // Sizes are bounded by the input's length (tensor data must be present in it), so this means the input is too big
    // for this machine.
    return absl::ResourceExhaustedError(absl::StrCat(where, ": out of memory reading ", bytes.size(), " bytes"));
  }
}

absl::StatusOr<Weights> load_weights(const std::string& path) {
  try {
    auto bytes = file_read_all(path);
    if (!bytes.ok()) return bytes.status();
    return parse_weights(*bytes, path);
  } catch (const std::bad_alloc&) {
    return absl::ResourceExhaustedError(absl::StrCat(path, ": out of memory reading the file"));
  }
}

std::string serialize_weights(const Weights& w) {
  json header = json::object();
  header["__metadata__"] = config_to_metadata(w.config);
  uint64_t offset = 0;
  for (const auto& [name, t] : w.tensors) {  // std::map: name order
    const uint64_t size = t.data.size() * sizeof(float);
    header[name] = {{"dtype", "F32"}, {"shape", t.shape}, {"data_offsets", json::array({offset, offset + size})}};
    offset += size;
  }
  // replace: a config name that is not UTF-8 must not throw; the loader then reports the mangled name.
  std::string text = json_text(header, -1);
  text.append((8 - text.size() % 8) % 8, ' ');
  std::string out;
  out.reserve(kHeaderLengthBytes + text.size() + offset);
  append_le64(out, text.size());
  out += text;
  for (const auto& [name, t] : w.tensors) append_f32(out, t.data);
  return out;
}

absl::Status save_weights(const std::string& path, const Weights& w) {
  // Never write what the loader would refuse.
  if (auto st = validate_weights(w, path); !st.ok()) return st;
  return file_write_atomically(path, serialize_weights(w));
}

}  // namespace ss
