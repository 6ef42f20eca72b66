// Atomic file output: a file is either written completely or not at all.
//
// WriteFileAtomically(path, contents) writes `contents` to a new temporary file
// in the directory of `path` (named ".<name>.tmp-<pid>-<n>", created with
// O_EXCL and mode 0666 & ~umask, or with the mode of the file it replaces),
// fsyncs it, renames it over `path` (atomic on POSIX file systems) and fsyncs
// the directory. On any failure the temporary file is removed, `path` is left
// as it was (absent or with its old contents) and an IoError names the path
// and the system error, e.g.
//   "out/spots.csv: cannot write: cannot create a temporary file in 'out':
//    No such file or directory"
// Readers never observe a partially written file.
#pragma once

#include <string>

#include "opl/core/status.h"

namespace opl {

Status WriteFileAtomically(const std::string& path, const std::string& contents);

// The same, streamed: for outputs too large to hold in memory (a point cloud
// of 10 million points). Open() creates the temporary file, Write() appends to
// it (unbuffered: give it large blocks, e.g. 1-4 MiB), Commit() fsyncs, renames
// it over the path and fsyncs the directory. Until Commit() succeeds `path` is
// untouched; Abandon() (or the destructor, or any failing call) removes the
// temporary file. Errors are IoErrors worded as WriteFileAtomically's.
//
//   AtomicFileWriter out;
//   OPL_RETURN_IF_ERROR(out.Open("cloud_mm.ply"));
//   while (...) OPL_RETURN_IF_ERROR(out.Write(block.data(), block.size()));
//   OPL_RETURN_IF_ERROR(out.Commit());
class AtomicFileWriter {
 public:
  AtomicFileWriter() = default;
  ~AtomicFileWriter();  // Abandon() unless committed
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

  // Creates the temporary file next to `path` (refused when already open).
  Status Open(const std::string& path);
  // Appends `size` bytes (retrying short writes and EINTR).
  Status Write(const char* data, size_t size);
  // Makes the file appear at `path`, complete. The writer is closed after.
  Status Commit();
  // Commit() in two steps, for files that must appear together
  // (io/output_set.h): Finish() fsyncs and closes the temporary file (its
  // data is on disk, `path` untouched); Publish() then renames it over `path`
  // and fsyncs the directory.
  Status Finish();
  Status Publish();
  // Closes and removes the temporary file; `path` stays as it was.
  void Abandon();

  bool is_open() const { return fd_ >= 0; }
  const std::string& path() const { return path_; }
  const std::string& temp_path() const { return temp_path_; }  // "" when closed
  long long bytes_written() const { return bytes_written_; }

 private:
  Status Fail(const std::string& what, int err);

  std::string path_, dir_, temp_path_;
  int fd_ = -1;
  long long bytes_written_ = 0;
};

// The largest input file a reader takes (docs/formats.md, "Limits"): a
// calibration session of two 201 x 201 grids on 20 screens is about 250 MB of
// spots CSV; a design's pattern file has at most 40401 beams (a few MB).
constexpr long long kMaxInputFileBytes = 512LL << 20;  // 512 MiB

// Reads a whole regular file of at most `max_bytes`. IoError
// "<path>: cannot open: <reason>" on failure (missing, unreadable),
// "<path>: cannot read: is a directory", "<path>: cannot read: not a regular
// file" (a device such as /dev/zero, a FIFO, a socket: they may never end),
// "<path>: cannot read: 600000000 bytes, more than the 536870912 an input may
// have". The size is checked before reading and the read is bounded (a file
// growing meanwhile is refused too).
Result<std::string> ReadFileToString(const std::string& path,
                                     long long max_bytes = kMaxInputFileBytes);

}  // namespace opl
