// Map encodings shared between sessions: a scenario's map is encoded once per (model, map content, focus) and handed
// to every session on it, read-only. Thread-safe. Entries live as long as a session holds them: an entry whose
// encoding no session holds any more is dropped when the next map is stored (each client-sent scenario with a map of
// its own would otherwise leave its entry, and with make_shared the encoding's own block, behind for good).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>

#include "absl/status/statusor.h"
#include "engine/model/model.h"
#include "engine/scenario/scenario.h"

namespace ss {

// A hash of what the encoding depends on: every map feature (kind, subtype, points) and the focus point the segments
// are ordered by.
uint64_t map_content_hash(const Scenario& s);

class MapCache {
 public:
  explicit MapCache(std::shared_ptr<const Model> model) : model_(std::move(model)) {}
  // The encoding of `s`'s map: segments nearest its focus (the SDC), at most the model's max_map_segments.
  absl::StatusOr<std::shared_ptr<const MapContext>> get(const Scenario& s);
  int encodes() const;  // how many encodings were computed (the rest were shared)
  size_t entries() const;  // maps remembered: only those some session still holds, plus at most the one just dropped

 private:
  std::shared_ptr<const Model> model_;
  mutable std::mutex mu_;
  std::map<uint64_t, std::weak_ptr<const MapContext>> maps_;
  int encodes_ = 0;
};

}  // namespace ss
