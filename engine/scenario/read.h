// Reading and writing scenario files. Errors name the file, the record and the field.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/scenario/scenario.h"

namespace ss {

// Reads every scenario in a file: GPUDrive/Nocturne JSON when the name ends in .json, a WOMD TFRecord of Scenario
// protos otherwise. Each scenario is validated (see validate.h).
absl::StatusOr<std::vector<Scenario>> read_scenarios(const std::string& path);

// Reads every scenario of every file given; a directory contributes its *.json and *.tfrecord* files in name order.
absl::StatusOr<std::vector<Scenario>> read_scenarios(const std::vector<std::string>& paths);

// Reads the scenarios of one file (JSON or TFRecord, as read_scenarios decides) one at a time, handing each to `fn`:
// a shard never has to fit in memory. Stops at the first error (the reader's or `fn`'s). Returns how many were read
// (0 for a TFRecord without records, which read_scenarios refuses).
absl::StatusOr<int> for_each_scenario(const std::string& path, const std::function<absl::Status(Scenario&&)>& fn);

// The scenario files `path` names, sorted by path: `path` itself when it is not a directory; otherwise the *.json and
// *.tfrecord* regular files in it (symlinks followed) and, with `recursive`, in its subdirectories too. NOT_FOUND if
// `path` does not exist; INVALID_ARGUMENT if a directory holds no scenario files.
absl::StatusOr<std::vector<std::string>> list_scenario_files(const std::string& path, bool recursive);

// Writes scenarios as one WOMD TFRecord file (one Scenario proto per record).
absl::Status write_scenarios_tfrecord(const std::string& path, const std::vector<Scenario>& scenarios);

}  // namespace ss
