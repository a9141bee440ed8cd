#include "server/session_id.h"

#include <random>

#include "absl/strings/str_cat.h"

namespace ss::server {

constexpr size_t kMaxIdLength = 128;
constexpr size_t kMaxEcho = 64;

std::string random_session_id() {
  std::random_device rd;
  static const char* hex = "0123456789abcdef";
  std::string s;
  for (int i = 0; i < 4; ++i) {
    uint32_t v = rd();
    for (int j = 0; j < 8; ++j) s += hex[(v >> (4 * j)) & 15];
  }
  return s;
}

absl::Status check_session_id(const std::string& id) {
  if (id.empty()) return absl::InvalidArgumentError("session_id is empty");
  if (id.size() > kMaxIdLength)
    return absl::InvalidArgumentError(absl::StrCat("session_id ", echo_id(id), ": longer than 128 characters"));
  for (char c : id)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.'))
      return absl::InvalidArgumentError(absl::StrCat("session_id ", echo_id(id), ": only letters, digits, '-', '_', '.'"));
  if (id[0] == '.') return absl::InvalidArgumentError(absl::StrCat("session_id ", echo_id(id), " must not start with '.'"));
  return absl::OkStatus();
}

std::string echo_id(const std::string& id) {
  if (id.size() <= kMaxEcho) return absl::StrCat("'", id, "'");
  return absl::StrCat("'", id.substr(0, kMaxEcho), "...' (", std::to_string(id.size()), " bytes)");
}

}  // namespace ss::server
