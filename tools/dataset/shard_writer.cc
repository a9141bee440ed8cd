#include "tools/dataset/shard_writer.h"

#include <filesystem>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "engine/scenario/read.h"
#include "engine/scenario/tfrecord.h"

namespace ss::dataset {

std::string shard_name(int index, int count) { return absl::StrFormat("sumo.tfrecord-%05d-of-%05d", index, count); }

ShardWriter::ShardWriter(std::string dir, int total_scenarios, int shard_size)
    : dir_(std::move(dir)), shard_size_(shard_size),
      shard_count_(std::max(1, (total_scenarios + shard_size - 1) / shard_size)) {}

absl::Status ShardWriter::add(std::string record, std::string id, const TokenizationFidelity& fidelity) {
  fidelity_.merge(fidelity);
  records_.push_back(std::move(record));
  ids_.push_back(std::move(id));
  if (static_cast<int>(records_.size()) == shard_size_) return flush();
  return absl::OkStatus();
}

absl::Status ShardWriter::finish() { return records_.empty() ? absl::OkStatus() : flush(); }

absl::Status ShardWriter::flush() {
  const std::string name = shard_name(next_shard_++, shard_count_);
  const std::string path = dir_ + "/" + name;
  if (auto st = write_tfrecord_file(path, records_); !st.ok()) return st;
  auto back = read_scenarios(path);
  if (!back.ok()) return absl::InternalError(absl::StrCat("validation: reading back ", path, ": ", back.status().message()));
  if (back->size() != ids_.size())
    return absl::InternalError(absl::StrCat("validation: ", path, " holds ", back->size(), " scenarios, ", ids_.size(),
                                            " were written"));
  for (size_t i = 0; i < back->size(); ++i) {
    const Scenario& s = (*back)[i];
    if (s.id != ids_[i])
      return absl::InternalError(absl::StrCat("validation: ", path, " record ", i, " is ", s.id, ", expected ", ids_[i]));
    ++validated_;
  }
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(path, ec);
  shard_list_.push_back({{"file", name}, {"scenarios", ids_.size()}, {"bytes", ec ? 0 : bytes}});
  records_.clear();
  ids_.clear();
  return absl::OkStatus();
}

}  // namespace ss::dataset
