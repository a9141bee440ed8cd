#include "engine/scenario/tfrecord.h"

#include <array>
#include <cerrno>
#include <cstring>
#include <sys/stat.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "engine/io/file_io.h"

namespace ss {
namespace {

// Slicing-by-8 tables: table[0] is the classic byte table; table[k] advances a byte that sits k bytes further back.
// Computed at compile time, so there is no lazily initialised global.
using CrcTables = std::array<std::array<uint32_t, 256>, 8>;

constexpr CrcTables make_crc_tables() {
  CrcTables t{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t c = i;
    for (int b = 0; b < 8; ++b) c = (c & 1) ? (c >> 1) ^ 0x82F63B78u : c >> 1;
    t[0][i] = c;
  }
  for (int k = 1; k < 8; ++k)
    for (uint32_t i = 0; i < 256; ++i) t[k][i] = (t[k - 1][i] >> 8) ^ t[0][t[k - 1][i] & 0xFF];
  return t;
}

constexpr CrcTables kCrcTables = make_crc_tables();

constexpr size_t kHeaderSize = 12;  // uint64 length + uint32 masked crc of the length
constexpr size_t kFooterSize = 4;   // uint32 masked crc of the data

uint64_t load_le64(const char* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | static_cast<uint8_t>(p[i]);
  return v;
}

uint32_t load_le32(const char* p) {
  uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | static_cast<uint8_t>(p[i]);
  return v;
}

void store_le(char* p, uint64_t v, int n) {
  for (int i = 0; i < n; ++i) p[i] = static_cast<char>((v >> (8 * i)) & 0xFF);
}

std::string record_where(const std::string& where, int index, uint64_t offset) {
  return absl::StrCat(where, " record ", index, " (byte offset ", offset, ")");
}

absl::Status bad(const std::string& where, int index, uint64_t offset, const std::string& what) {
  return absl::InvalidArgumentError(absl::StrCat(record_where(where, index, offset), ": ", what));
}

// Checks a record's header against what the file still holds after it; returns the data length.
absl::StatusOr<uint64_t> check_header(const char* header, uint64_t remaining, const std::string& where, int index,
                                      uint64_t offset) {
  const uint64_t length = load_le64(header);
  const uint32_t stored = load_le32(header + 8);
  const uint32_t computed = mask_crc(crc32c(std::string_view(header, 8)));
  // The CRC first: a corrupt length would otherwise be misreported as truncation or as an absurd size.
  if (stored != computed)
    return bad(where, index, offset,
               absl::StrFormat("length CRC mismatch (stored 0x%08x, computed 0x%08x): the header is corrupt", stored,
                               computed));
  if (length > kMaxTfRecordLength)
    return bad(where, index, offset, absl::StrCat("length ", length, " exceeds the limit of ", kMaxTfRecordLength,
                                                  " bytes"));
  if (length > remaining)
    return bad(where, index, offset,
               absl::StrCat("truncated data: length ", length, " but only ", remaining, " bytes follow the header"));
  if (remaining - length < kFooterSize)
    return bad(where, index, offset,
               absl::StrCat("truncated footer: ", remaining - length, " of ", kFooterSize, " bytes"));
  return length;
}

absl::Status check_data_crc(std::string_view data, const char* footer, const std::string& where, int index,
                            uint64_t offset) {
  const uint32_t stored = load_le32(footer);
  const uint32_t computed = mask_crc(crc32c(data));
  if (stored != computed)
    return bad(where, index, offset,
               absl::StrFormat("data CRC mismatch (stored 0x%08x, computed 0x%08x) over %d bytes: the data is corrupt",
                               stored, computed, data.size()));
  return absl::OkStatus();
}

}  // namespace

uint32_t crc32c_extend(uint32_t crc, std::string_view data) {
  const auto& t = kCrcTables;
  const auto* p = reinterpret_cast<const uint8_t*>(data.data());
  size_t n = data.size();
  uint32_t c = ~crc;
  while (n >= 8) {
    const uint32_t lo = c ^ (uint32_t{p[0]} | uint32_t{p[1]} << 8 | uint32_t{p[2]} << 16 | uint32_t{p[3]} << 24);
    c = t[7][lo & 0xFF] ^ t[6][(lo >> 8) & 0xFF] ^ t[5][(lo >> 16) & 0xFF] ^ t[4][lo >> 24] ^ t[3][p[4]] ^
        t[2][p[5]] ^ t[1][p[6]] ^ t[0][p[7]];
    p += 8;
    n -= 8;
  }
  while (n--) c = (c >> 8) ^ t[0][(c ^ *p++) & 0xFF];
  return ~c;
}

uint32_t crc32c(std::string_view data) { return crc32c_extend(0, data); }

uint32_t mask_crc(uint32_t crc) { return ((crc >> 15) | (crc << 17)) + 0xA282EAD8u; }

uint32_t unmask_crc(uint32_t masked) {
  const uint32_t rot = masked - 0xA282EAD8u;
  return (rot >> 17) | (rot << 15);
}

absl::StatusOr<std::vector<std::string>> parse_tfrecords(std::string_view bytes, const std::string& where) {
  std::vector<std::string> records;
  uint64_t offset = 0;
  for (int index = 0; offset < bytes.size(); ++index) {
    const uint64_t left = bytes.size() - offset;
    if (left < kHeaderSize)
      return bad(where, index, offset, absl::StrCat("truncated header: ", left, " of ", kHeaderSize, " bytes"));
    const char* header = bytes.data() + offset;
    auto length = check_header(header, left - kHeaderSize, where, index, offset);
    if (!length.ok()) return length.status();
    std::string_view data = bytes.substr(offset + kHeaderSize, *length);
    if (auto st = check_data_crc(data, header + kHeaderSize + *length, where, index, offset); !st.ok()) return st;
    records.emplace_back(data);
    offset += kHeaderSize + *length + kFooterSize;
  }
  return records;
}

absl::StatusOr<TfRecordReader> TfRecordReader::open(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return errno_status(errno, path);
  struct stat sb;
  if (fstat(fileno(f), &sb) != 0) {
    const int err = errno;
    std::fclose(f);
    return errno_status(err, path);
  }
  if (!S_ISREG(sb.st_mode)) {
    std::fclose(f);
    return absl::InvalidArgumentError(absl::StrCat(path, ": not a regular file"));
  }
  return TfRecordReader(path, f, static_cast<uint64_t>(sb.st_size));
}

absl::StatusOr<bool> TfRecordReader::next(std::string* record) {
  std::FILE* f = file_.get();
  char header[kHeaderSize];
  const size_t got = std::fread(header, 1, kHeaderSize, f);
  if (std::ferror(f)) return absl::InternalError(absl::StrCat(record_where(path_, index_, offset_), ": read failed"));
  if (got == 0) return false;
  if (got < kHeaderSize) {
    std::fseek(f, static_cast<long>(offset_), SEEK_SET);
    return bad(path_, index_, offset_, absl::StrCat("truncated header: ", got, " of ", kHeaderSize, " bytes"));
  }
  // The file may have shrunk since open(); a short read below is reported as truncation as well.
  const uint64_t left = size_ > offset_ + kHeaderSize ? size_ - offset_ - kHeaderSize : 0;
  auto length = check_header(header, left, path_, index_, offset_);
  if (!length.ok()) {
    std::fseek(f, static_cast<long>(offset_), SEEK_SET);
    return length.status();
  }
  record->resize(*length);
  char footer[kFooterSize];
  if (std::fread(record->data(), 1, *length, f) != *length || std::fread(footer, 1, kFooterSize, f) != kFooterSize) {
    std::fseek(f, static_cast<long>(offset_), SEEK_SET);
    return bad(path_, index_, offset_, "truncated record: the file ended while reading it");
  }
  if (auto st = check_data_crc(*record, footer, path_, index_, offset_); !st.ok()) {
    std::fseek(f, static_cast<long>(offset_), SEEK_SET);
    return st;
  }
  offset_ += kHeaderSize + *length + kFooterSize;
  ++index_;
  return true;
}

absl::StatusOr<std::vector<std::string>> read_tfrecord_file(const std::string& path) {
  auto reader = TfRecordReader::open(path);
  if (!reader.ok()) return reader.status();
  std::vector<std::string> records;
  std::string record;
  while (true) {
    auto more = reader->next(&record);
    if (!more.ok()) return more.status();
    if (!*more) break;
    records.push_back(std::move(record));
  }
  return records;
}

std::string tfrecord_frame(std::string_view data) {
  std::string out(kHeaderSize + data.size() + kFooterSize, '\0');
  store_le(out.data(), data.size(), 8);
  store_le(out.data() + 8, mask_crc(crc32c(std::string_view(out.data(), 8))), 4);
  if (!data.empty()) std::memcpy(out.data() + kHeaderSize, data.data(), data.size());
  store_le(out.data() + kHeaderSize + data.size(), mask_crc(crc32c(data)), 4);
  return out;
}

absl::Status write_tfrecord_file(const std::string& path, const std::vector<std::string>& records) {
  // Never write what the reader would refuse.
  for (size_t i = 0; i < records.size(); ++i)
    if (records[i].size() > kMaxTfRecordLength)
      return absl::InvalidArgumentError(absl::StrCat(path, " record ", i, ": ", records[i].size(),
                                                     " bytes exceeds the limit of ", kMaxTfRecordLength));
  // The whole file is framed in memory (one more copy of the records) so that it is written atomically in one go.
  size_t size = 0;
  for (const std::string& r : records) size += kHeaderSize + r.size() + kFooterSize;
  std::string bytes;
  bytes.reserve(size);
  for (const std::string& r : records) bytes += tfrecord_frame(r);
  return file_write_atomically(path, bytes);
}

}  // namespace ss
