#include "engine/io/record.h"

#include <cstdint>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "engine/base/rng.h"
#include "engine/scenario/tfrecord.h"

namespace ss {
namespace {

constexpr size_t kMagicSize = 8;
constexpr size_t kHashSize = 8;

uint64_t load_le64(const char* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | static_cast<uint8_t>(p[i]);
  return v;
}

std::string_view family(const RecordFormat& f) { return f.magic.substr(0, f.magic.size() - f.version_chars); }

// FAILED_PRECONDITION naming both versions when `magic` is another version of the format; OK when it is this one.
absl::Status check_version(const RecordFormat& f, std::string_view magic) {
  if (magic == f.magic) return absl::OkStatus();
  const std::string reader(f.reader);
  return absl::FailedPreconditionError(
      absl::StrCat(std::string(f.what), ": format ", std::string(magic), " is not this ", reader, "'s ",
                   std::string(f.magic), " (version ", std::string(magic.substr(kMagicSize - f.version_chars)),
                   " is not this ", reader, "'s version ", std::string(f.magic.substr(kMagicSize - f.version_chars)),
                   ")"));
}

// The layout before the framing: the magic first, with an FNV-1a hash of the message before or after it.
absl::StatusOr<std::string> read_earlier(const RecordFormat& f, std::string_view bytes) {
  if (auto st = check_version(f, bytes.substr(0, kMagicSize)); !st.ok()) return st;
  if (bytes.size() < kMagicSize + kHashSize)
    return absl::DataLossError(absl::StrCat(std::string(f.what), ": checksum mismatch: ", std::to_string(bytes.size()),
                                            " bytes are too few for the magic and the hash (truncated)"));
  const bool hash_first = f.earlier == RecordFormat::Earlier::hash_then_message;
  const std::string_view message = hash_first ? bytes.substr(kMagicSize + kHashSize)
                                              : bytes.substr(kMagicSize, bytes.size() - kMagicSize - kHashSize);
  const uint64_t stored = load_le64(hash_first ? bytes.data() + kMagicSize : bytes.data() + bytes.size() - kHashSize);
  // The later layout hashed the magic with the message; the earlier one the message alone.
  const uint64_t actual = hash_first ? fnv1a64(message) : fnv1a64(bytes.substr(0, bytes.size() - kHashSize));
  if (stored != actual)
    return absl::DataLossError(absl::StrFormat("%s: checksum mismatch (the bytes say %016x, they hash to %016x): "
                                               "truncated or corrupt",
                                               std::string(f.what), stored, actual));
  return std::string(message);
}

}  // namespace

std::string record_write(const RecordFormat& f, std::string_view message) {
  std::string data(f.magic);
  data.append(message);
  return tfrecord_frame(data);
}

absl::StatusOr<std::string> record_read(const RecordFormat& f, std::string_view bytes) {
  // A framed record begins with its length, under 2^30: its high bytes are zero, so never the magic's letters.
  if (bytes.size() >= kMagicSize && bytes.substr(0, family(f).size()) == family(f)) return read_earlier(f, bytes);
  auto records = parse_tfrecords(bytes, "the framed");  // "the framed record 0 (byte offset 0): ..."
  if (!records.ok()) {
    // Any framing error of bytes that are long enough to hold one is a cut or a flipped bit.
    if (bytes.size() < 12)  // not even a record header
      return absl::InvalidArgumentError(absl::StrCat(std::string(f.what), ": not a ", std::string(f.what), " (",
                                                     std::to_string(bytes.size()), " bytes, no record)"));
    return absl::DataLossError(
        absl::StrCat(std::string(f.what), ": checksum mismatch or cut: ", std::string(records.status().message())));
  }
  if (records->size() != 1)
    return absl::DataLossError(
        absl::StrCat(std::string(f.what), ": ", std::to_string(records->size()), " records where one was written"));
  const std::string& data = records->front();
  if (data.size() < kMagicSize || data.substr(0, family(f).size()) != family(f))
    return absl::InvalidArgumentError(absl::StrCat(std::string(f.what), ": not a ", std::string(f.what), " (no ",
                                                   std::string(family(f)), " magic)"));
  if (auto st = check_version(f, std::string_view(data).substr(0, kMagicSize)); !st.ok()) return st;
  return data.substr(kMagicSize);
}

}  // namespace ss
