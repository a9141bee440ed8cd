// Writes a generated dataset's scenarios, in order, into TFRecord shards of a fixed size, and checks each shard once
// written: read back with the engine's reader (framing, CRCs, wire check, conversion, validation), ids checked
// against what was written. (The jobs tokenized every scenario already, in parallel; their measurements are summed
// here for the scenarios the dataset keeps.)
#pragma once

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "engine/tokens/fidelity.h"
#include "nlohmann/json.hpp"

namespace ss::dataset {

// WOMD's naming: <name>.tfrecord-00003-of-00012.
std::string shard_name(int index, int count);

class ShardWriter {
 public:
  ShardWriter(std::string dir, int total_scenarios, int shard_size);

  // Adds one serialized Scenario; writes and validates a shard whenever one is full.
  absl::Status add(std::string record, std::string id, const TokenizationFidelity& fidelity);
  // Writes the last, partial shard.
  absl::Status finish();

  int shards() const { return shard_count_; }
  // [{"file", "scenarios", "bytes"}] of the shards written.
  const nlohmann::ordered_json& shard_list() const { return shard_list_; }
  const TokenizationFidelity& fidelity() const { return fidelity_; }
  int validated() const { return validated_; }

 private:
  absl::Status flush();

  std::string dir_;
  int shard_size_, shard_count_, next_shard_ = 0;
  std::vector<std::string> records_, ids_;
  nlohmann::ordered_json shard_list_ = nlohmann::ordered_json::array();
  TokenizationFidelity fidelity_;
  int validated_ = 0;
};

}  // namespace ss::dataset
