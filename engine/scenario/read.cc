#include "engine/scenario/read.h"

#include <algorithm>
#include <filesystem>
#include <functional>
#include <system_error>

#include "absl/strings/str_cat.h"
#include "engine/io/file_io.h"
#include "engine/scenario/gpudrive_json.h"
#include "engine/scenario/tfrecord.h"
#include "engine/scenario/validate.h"
#include "engine/scenario/womd_proto.h"

namespace ss {
namespace {

namespace fs = std::filesystem;

bool is_json_name(const std::string& name) { return name.size() >= 5 && name.ends_with(".json"); }
// WOMD shards are named like "training.tfrecord-00000-of-01000", hence "contains" rather than "ends with".
bool is_tfrecord_name(const std::string& name) { return name.find(".tfrecord") != std::string::npos; }

absl::Status not_found(const std::string& path) {
  return absl::NotFoundError(absl::StrCat(path, ": no such file or directory"));
}

absl::Status read_file(const std::string& path, std::vector<Scenario>* out) {
  auto count = for_each_scenario(path, [&](Scenario&& s) {
    out->push_back(std::move(s));
    return absl::OkStatus();
  });
  if (!count.ok()) return count.status();
  if (*count == 0) return absl::InvalidArgumentError(absl::StrCat(path, ": holds no scenarios (no TFRecord records)"));
  return absl::OkStatus();
}

absl::Status read_path(const std::string& path, std::vector<Scenario>* out) {
  auto files = list_scenario_files(path, /*recursive=*/false);
  if (!files.ok()) return files.status();
  for (const std::string& f : *files)
    if (auto st = read_file(f, out); !st.ok()) return st;
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<int> for_each_scenario(const std::string& path, const std::function<absl::Status(Scenario&&)>& fn) {
  if (is_json_name(fs::path(path).filename().string())) {
    auto text = file_read_all(path);  // says why a file cannot be read (missing, a directory, no permission)
    if (!text.ok()) return text.status();
    auto s = scenario_from_gpudrive_json(*text, path);
    if (!s.ok()) return s.status();
    if (auto st = fn(std::move(*s)); !st.ok()) return st;
    return 1;
  }
  // One record at a time: a WOMD shard is hundreds of megabytes, and only what `fn` keeps needs to stay.
  auto reader = TfRecordReader::open(path);
  if (!reader.ok()) return reader.status();
  std::string record;
  while (true) {
    const int index = reader->records_read();
    auto more = reader->next(&record);
    if (!more.ok()) return more.status();
    if (!*more) break;
    auto s = scenario_from_womd_bytes(record, absl::StrCat(path, " record ", index));
    if (!s.ok()) return s.status();
    if (auto st = fn(std::move(*s)); !st.ok()) return st;
  }
  return reader->records_read();
}

absl::StatusOr<std::vector<std::string>> list_scenario_files(const std::string& path, bool recursive) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) return not_found(path);
  if (!fs::is_directory(st)) return std::vector<std::string>{path};
  std::vector<std::string> files;
  // One iterator for both cases: when not recursive, it is kept from descending into each directory it meets.
  for (fs::recursive_directory_iterator it(path, fs::directory_options::follow_directory_symlink, ec), end;
       !ec && it != end; it.increment(ec)) {
    if (!recursive) it.disable_recursion_pending();
    const std::string name = it->path().filename().string();
    if (!is_json_name(name) && !is_tfrecord_name(name)) continue;
    std::error_code fec;
    if (!it->is_regular_file(fec)) continue;  // also follows symlinks
    files.push_back(it->path().string());
  }
  if (ec) return absl::InternalError(absl::StrCat(path, ": cannot list the directory: ", ec.message()));
  if (files.empty()) return absl::InvalidArgumentError(absl::StrCat(path, ": holds no *.json or *.tfrecord* files"));
  std::sort(files.begin(), files.end());
  return files;
}

absl::StatusOr<std::vector<Scenario>> read_scenarios(const std::string& path) {
  std::vector<Scenario> out;
  if (auto st = read_path(path, &out); !st.ok()) return st;
  return out;
}

absl::StatusOr<std::vector<Scenario>> read_scenarios(const std::vector<std::string>& paths) {
  if (paths.empty()) return absl::InvalidArgumentError("read_scenarios: no paths given");
  std::vector<Scenario> out;
  for (const std::string& p : paths)
    if (auto st = read_path(p, &out); !st.ok()) return st;
  return out;
}

absl::Status write_scenarios_tfrecord(const std::string& path, const std::vector<Scenario>& scenarios) {
  // A file with no records would not read back (read_scenarios rejects it), so do not write one.
  if (scenarios.empty()) return absl::InvalidArgumentError(absl::StrCat(path, ": no scenarios to write"));
  std::vector<std::string> records;
  records.reserve(scenarios.size());
  for (size_t i = 0; i < scenarios.size(); ++i) {
    const std::string where = absl::StrCat(path, " scenario ", i);
    // Only what reads back: the reader validates every scenario.
    if (auto st = validate_scenario(scenarios[i], where); !st.ok()) return st;
    auto bytes = encode_womd_scenario(scenarios[i], where);
    if (!bytes.ok()) return bytes.status();
    records.push_back(std::move(*bytes));
  }
  return write_tfrecord_file(path, records);
}

}  // namespace ss
