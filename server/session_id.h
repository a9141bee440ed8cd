// Session ids: random ones, the rule a client-proposed id must follow (it also makes an id safe as a file name), and
// how an id a client sent is echoed in errors (cut short: a huge id must not turn an error into a metadata overflow).
#pragma once

#include <string>

#include "absl/status/status.h"

namespace ss::server {

// 128 random bits from the kernel's CSPRNG, as 32 hex digits: ids are unguessable.
std::string random_session_id();
// OK when `id` is 1-128 letters, digits, '-', '_', '.' and does not start with '.'; else INVALID_ARGUMENT.
absl::Status check_session_id(const std::string& id);
// `id` quoted for a message, cut to its first 64 bytes (the length said) when longer.
std::string echo_id(const std::string& id);

}  // namespace ss::server
