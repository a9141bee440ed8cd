// Whole files: read in one go, or written atomically (a temporary file renamed into place). Errors name the path and
// what failed, with the system's reason.
#pragma once

#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace ss {

// An errno value as a status "<what>: <strerror(err)>": NOT_FOUND for a missing file or directory (ENOENT, ENOTDIR),
// PERMISSION_DENIED for EACCES, EPERM and EROFS, INTERNAL otherwise.
absl::Status errno_status(int err, const std::string& what);

// A regular file's bytes. NOT_FOUND if it does not exist; INVALID_ARGUMENT if it is not a regular file (a directory,
// a pipe); DATA_LOSS if it shrank while being read.
absl::StatusOr<std::string> file_read_all(const std::string& path);

// Writes `bytes` to a temporary file next to `path`, syncs it, renames it over `path` and syncs the directory: a
// reader sees the old file or the new one, never half of one, a failed write leaves the old file as it was, and once
// this returns OK the new file survives a crash. The temporary file is removed on failure. NOT_FOUND if the directory
// does not exist. `mode` is the new file's permissions (less the umask); 0600 keeps it to its owner from the first
// byte on.
absl::Status file_write_atomically(const std::string& path, std::string_view bytes, int mode = 0666);

}  // namespace ss
