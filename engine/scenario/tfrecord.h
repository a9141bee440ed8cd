// TFRecord files: the container WOMD ships its Scenario protos in. Framing, little-endian, repeated to end of file:
//   uint64 length | uint32 masked_crc32c(length bytes) | data[length] | uint32 masked_crc32c(data)
// Readers check both CRCs and report truncation and corruption with the file, the record index and the byte offset.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace ss {

// CRC-32C (Castagnoli: reflected polynomial 0x82F63B78, init and final xor 0xFFFFFFFF).
uint32_t crc32c(std::string_view data);
// Continues a CRC-32C: crc32c_extend(crc32c(a), b) == crc32c(a + b).
uint32_t crc32c_extend(uint32_t crc, std::string_view data);
// TFRecord stores masked CRCs so that a CRC of data that itself holds CRCs stays well distributed.
uint32_t mask_crc(uint32_t crc);
uint32_t unmask_crc(uint32_t masked);

// A record longer than this is taken as corruption: checked before anything is allocated.
inline constexpr uint64_t kMaxTfRecordLength = uint64_t{1} << 30;

// Parses TFRecord-framed bytes held in memory. `where` names the source (a file name) in error messages.
absl::StatusOr<std::vector<std::string>> parse_tfrecords(std::string_view bytes, const std::string& where);

// Reads one record at a time, so a large file never has to be in memory at once.
class TfRecordReader {
 public:
  // NOT_FOUND when the file does not exist or cannot be opened.
  static absl::StatusOr<TfRecordReader> open(const std::string& path);

  // The next record into `*record`: true, or false at a clean end of file. Errors are INVALID_ARGUMENT (bad data)
  // or INTERNAL (read failure); after an error the reader stays at the failed record.
  absl::StatusOr<bool> next(std::string* record);

  int records_read() const { return index_; }
  const std::string& path() const { return path_; }

 private:
  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  TfRecordReader(std::string path, std::FILE* f, uint64_t size) : path_(std::move(path)), file_(f), size_(size) {}

  std::string path_;
  std::unique_ptr<std::FILE, Closer> file_;
  uint64_t size_ = 0;    // file size at open: lengths are checked against it before allocating
  uint64_t offset_ = 0;  // of the next record
  int index_ = 0;        // of the next record
};

// Every record of a file (see TfRecordReader). A file with no records gives an empty vector.
absl::StatusOr<std::vector<std::string>> read_tfrecord_file(const std::string& path);

// One record's framing around `data`.
std::string tfrecord_frame(std::string_view data);

// Writes the records to a temporary file next to `path`, then renames it over `path`, so a reader never sees a
// half-written file.
absl::Status write_tfrecord_file(const std::string& path, const std::vector<std::string>& records);

}  // namespace ss
