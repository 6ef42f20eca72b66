#include "opl/io/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

namespace opl {
namespace {

std::string ErrnoText(int err) { return std::strerror(err); }

Status WriteError(const std::string& path, const std::string& what, int err) {
  return Status::IoError(path + ": cannot write: " + what +
                         (err != 0 ? ": " + ErrnoText(err) : std::string()));
}

// Splits "dir/name" into ("dir", "name"); "name" gives (".", "name").
void SplitPath(const std::string& path, std::string* dir, std::string* name) {
  const size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) {
    *dir = ".";
    *name = path;
  } else {
    *dir = slash == 0 ? "/" : path.substr(0, slash);
    *name = path.substr(slash + 1);
  }
}

// Writes all of `data`, retrying on EINTR and short writes. Returns 0 or errno.
int WriteAll(int fd, const char* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    data += n;
    size -= static_cast<size_t>(n);
  }
  return 0;
}

}  // namespace

AtomicFileWriter::~AtomicFileWriter() { Abandon(); }

Status AtomicFileWriter::Fail(const std::string& what, int err) {
  const std::string path = path_;
  Abandon();
  return WriteError(path, what, err);
}

void AtomicFileWriter::Abandon() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!temp_path_.empty()) ::unlink(temp_path_.c_str());
  temp_path_.clear();
}

Status AtomicFileWriter::Open(const std::string& path) {
  if (fd_ >= 0) return WriteError(path, "the writer is already open for '" + path_ + "'", 0);
  path_ = path;
  bytes_written_ = 0;
  std::string name;
  SplitPath(path, &dir_, &name);
  if (name.empty() || name == "." || name == "..") {
    return WriteError(path, "not a file name", 0);
  }
  struct stat target_stat;
  const bool target_exists = ::stat(path.c_str(), &target_stat) == 0;

  // A fresh temporary name in the same directory (so that rename is atomic).
  static std::atomic<unsigned> counter{0};
  int fd = -1;
  for (int attempt = 0; attempt < 100 && fd < 0; ++attempt) {
    temp_path_ = (dir_ == "/" ? std::string("/") : dir_ + "/") + "." + name + ".tmp-" +
                 std::to_string(::getpid()) + "-" + std::to_string(counter++);
    fd = ::open(temp_path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0) {
    const int err = errno;
    temp_path_.clear();
    return WriteError(path, "cannot create a temporary file in '" + dir_ + "'", err);
  }
  fd_ = fd;
  // Keep the permissions of a file we replace. (A directory at `path` is not
  // checked up front: rename fails on it, which cleans up like any failure.)
  if (target_exists && S_ISREG(target_stat.st_mode) &&
      ::fchmod(fd_, target_stat.st_mode & 07777) != 0) {
    return Fail("cannot set permissions", errno);
  }
  return Status::Ok();
}

Status AtomicFileWriter::Write(const char* data, size_t size) {
  if (fd_ < 0) return WriteError(path_, "the writer is not open", 0);
  if (int err = WriteAll(fd_, data, size); err != 0) return Fail("write failed", err);
  bytes_written_ += static_cast<long long>(size);
  return Status::Ok();
}

Status AtomicFileWriter::Finish() {
  if (fd_ < 0) return WriteError(path_, "the writer is not open", 0);
  if (::fsync(fd_) != 0) return Fail("fsync failed", errno);
  const int close_result = ::close(fd_);
  fd_ = -1;
  if (close_result != 0) return Fail("close failed", errno);
  return Status::Ok();
}

Status AtomicFileWriter::Publish() {
  if (fd_ >= 0 || temp_path_.empty()) return WriteError(path_, "the writer is not finished", 0);
  if (::rename(temp_path_.c_str(), path_.c_str()) != 0) return Fail("rename failed", errno);
  temp_path_.clear();
  // Make the rename durable; failure here does not undo a completed write.
  const int dir_fd = ::open(dir_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd >= 0) {
    (void)::fsync(dir_fd);
    ::close(dir_fd);
  }
  return Status::Ok();
}

Status AtomicFileWriter::Commit() {
  OPL_RETURN_IF_ERROR(Finish());
  return Publish();
}

Status WriteFileAtomically(const std::string& path, const std::string& contents) {
  AtomicFileWriter writer;
  OPL_RETURN_IF_ERROR(writer.Open(path));
  OPL_RETURN_IF_ERROR(writer.Write(contents.data(), contents.size()));
  return writer.Commit();
}

Result<std::string> ReadFileToString(const std::string& path, long long max_bytes) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    return Status::IoError(path + ": cannot open: " + ErrnoText(errno));
  }
  if (S_ISDIR(st.st_mode)) return Status::IoError(path + ": cannot read: is a directory");
  if (!S_ISREG(st.st_mode)) {
    return Status::IoError(path + ": cannot read: not a regular file (a device, FIFO or socket)");
  }
  auto too_big = [&](long long bytes) {
    return Status::IoError(path + ": cannot read: " + std::to_string(bytes) +
                           " bytes, more than the " + std::to_string(max_bytes) +
                           " an input may have");
  };
  if (st.st_size > max_bytes) return too_big(st.st_size);
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IoError(path + ": cannot open: " + ErrnoText(errno));
  std::string text(static_cast<size_t>(st.st_size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  if (in.bad()) return Status::IoError(path + ": read error");
  text.resize(static_cast<size_t>(in.gcount()));
  // A file that grew since stat: read on, but never past the limit.
  char chunk[65536];
  while (in && !in.eof()) {
    in.read(chunk, sizeof chunk);
    if (in.bad()) return Status::IoError(path + ": read error");
    text.append(chunk, static_cast<size_t>(in.gcount()));
    if (static_cast<long long>(text.size()) > max_bytes) {
      return too_big(static_cast<long long>(text.size()));
    }
  }
  return text;
}

}  // namespace opl
