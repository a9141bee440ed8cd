#include "server/watch_hub.h"

#include <string>

#include "absl/strings/str_cat.h"

namespace ss::server {

void SessionWatchers::add(std::shared_ptr<TickWatcher> w, const TickView& current) {
  watchers_.push_back(std::move(w));
  watchers_.back()->on_tick(current);
}

void SessionWatchers::publish(const TickView& t) {
  std::erase_if(watchers_, [](const auto& w) { return w->done(); });
  for (const auto& w : watchers_) w->on_tick(t);
}

void SessionWatchers::end() {
  for (const auto& w : watchers_) w->on_end();
  watchers_.clear();
}

absl::Status WatchHub::reserve() {
  if (++open_ > max_) {
    --open_;
    return absl::ResourceExhaustedError(
        absl::StrCat("--max_watchers=", std::to_string(max_), " watch streams are open: close one first"));
  }
  return absl::OkStatus();
}

}  // namespace ss::server
