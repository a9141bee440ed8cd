#include "engine/io/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace ss {

absl::Status errno_status(int err, const std::string& what) {
  const std::string msg = absl::StrCat(what, ": ", std::strerror(err));
  switch (err) {
    case ENOENT:
    case ENOTDIR:
      return absl::NotFoundError(msg);
    case EACCES:
    case EPERM:
    case EROFS:
      return absl::PermissionDeniedError(msg);
    default:
      return absl::InternalError(msg);
  }
}

absl::StatusOr<std::string> file_read_all(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (f == nullptr) return errno_status(errno, absl::StrCat(path, ": cannot open"));
  struct stat sb;
  if (::fstat(::fileno(f.get()), &sb) != 0) return errno_status(errno, absl::StrCat(path, ": cannot stat"));
  // The size comes from fstat, so a directory or a pipe would read as empty: refuse them instead.
  if (!S_ISREG(sb.st_mode)) return absl::InvalidArgumentError(absl::StrCat(path, ": not a regular file"));
  std::string bytes(static_cast<size_t>(sb.st_size), '\0');
  const size_t got = std::fread(bytes.data(), 1, bytes.size(), f.get());
  if (got != bytes.size())
    return std::ferror(f.get()) ? errno_status(errno, absl::StrCat(path, ": read failed"))
                                : absl::DataLossError(absl::StrCat(path, ": read ", got, " of ", bytes.size(),
                                                                   " bytes: the file shrank while being read"));
  return bytes;
}

// The temporary file sits in the target's directory so that rename() is atomic (same filesystem). open() with O_EXCL
// rather than mkstemp(): mkstemp makes the file 0600, and fixing that up would need the process umask.
absl::Status file_write_atomically(const std::string& path, std::string_view bytes, int mode) {
  std::random_device rd;
  std::string tmp;
  int fd = -1;
  for (int attempt = 0; attempt < 8 && fd < 0; ++attempt) {
    tmp = absl::StrFormat("%s.tmp.%d.%08x", path, static_cast<int>(::getpid()), rd());
    fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, static_cast<mode_t>(mode));
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0) return errno_status(errno, absl::StrCat(path, ": cannot create a temporary file ", tmp));
  // The temporary file's name begins with `path`, so messages naming it name the target too.
  auto fail = [&](int err, const std::string& what) {
    ::unlink(tmp.c_str());
    return errno_status(err, absl::StrCat(tmp, ": ", what));
  };
  const char* p = bytes.data();
  size_t left = bytes.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      return fail(err, "write failed");
    }
    p += n;
    left -= static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    return fail(err, "fsync failed");
  }
  if (::close(fd) != 0) return fail(errno, "close failed");
  if (std::rename(tmp.c_str(), path.c_str()) != 0) return fail(errno, absl::StrCat("cannot rename to ", path));
  // The rename is durable once the directory is synced too. Filesystems that cannot sync a directory say EINVAL.
  const std::string dir = std::filesystem::path(path).parent_path().string();
  const int dfd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd < 0) return errno_status(errno, absl::StrCat(path, ": written, but its directory cannot be opened"));
  const int synced = ::fsync(dfd);
  const int err = errno;
  ::close(dfd);
  if (synced != 0 && err != EINVAL)
    return errno_status(err, absl::StrCat(path, ": written, but its directory could not be synced"));
  return absl::OkStatus();
}

}  // namespace ss
