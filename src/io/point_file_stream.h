// Private to src/io: the buffered input and output that the streaming point
// file scalers (PLY, XYZ, points CSV; opl/io/scale_point_file.h) share, and
// their entry points. Memory is the two buffers, whatever the file's size.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/io/atomic_file.h"

namespace opl {
namespace point_file_internal {

// A regular file read through one buffer. The window [data(), data() + size())
// holds the unconsumed bytes; Fill() moves them to the front and reads more.
class InputFile {
 public:
  // IoError "<path>: cannot open: <reason>", "<path>: cannot read: is a
  // directory", "<path>: cannot read: not a regular file (...)".
  Status Open(const std::string& path, size_t buffer_bytes);
  ~InputFile();

  const char* data() const { return buffer_.get() + begin_; }
  char* mutable_data() { return buffer_.get() + begin_; }
  size_t size() const { return end_ - begin_; }
  void Consume(size_t n) { begin_ += n; }
  // Reads more (after moving the window to the front). Returns the number of
  // bytes added: 0 at the end of the file, or when the buffer is full.
  Result<size_t> Fill();
  // Fills until at least `n` bytes are in the window or the file ends.
  Status Ensure(size_t n);
  bool at_eof() const { return eof_; }
  bool full() const { return size() == capacity_; }
  size_t capacity() const { return capacity_; }
  // File offset of data()[0].
  int64_t offset() const { return file_offset_ - static_cast<int64_t>(end_ - begin_); }
  int64_t file_size() const { return file_size_; }
  const std::string& path() const { return path_; }

  // Called after every read with (bytes read so far, file size).
  std::function<void(int64_t, int64_t)> progress;

 private:
  std::string path_;
  int fd_ = -1;
  std::unique_ptr<char[]> buffer_;  // not zero-filled: pages are touched only when read into
  size_t capacity_ = 0;
  size_t begin_ = 0, end_ = 0;
  int64_t file_offset_ = 0;  // bytes read from the file so far
  int64_t file_size_ = 0;
  bool eof_ = false;
};

// Output gathered in one buffer and written to an AtomicFileWriter in large
// blocks. A null writer discards everything (checking an input only).
class OutputBuffer {
 public:
  OutputBuffer(AtomicFileWriter* writer, size_t buffer_bytes);

  void Append(const char* p, size_t n) {
    if (size_ + n > buffer_.size()) {
      AppendSlow(p, n);
      return;
    }
    std::memcpy(buffer_.data() + size_, p, n);
    size_ += n;
  }
  void Append(const std::string& s) { Append(s.data(), s.size()); }
  // Room for at least `n` more bytes (n <= the buffer size) at the end; then
  // Commit(k) keeps k of them.
  char* Reserve(size_t n) {
    if (size_ + n > buffer_.size()) Flush();
    return buffer_.data() + size_;
  }
  void Commit(size_t k) { size_ += k; }
  // Writes what is buffered. The first write failure is kept in status().
  void Flush();
  const Status& status() const { return status_; }
  bool failed() const { return !status_.ok(); }

 private:
  void AppendSlow(const char* p, size_t n);

  AtomicFileWriter* writer_;
  std::vector<char> buffer_;
  size_t size_ = 0;
  Status status_;
};

// What a format's scaler reports back.
struct ScaleCounts {
  int64_t num_points = 0;  // points (vertices, rows, lines) scaled
};

// The scalers: read `in` from its start, write the scaled file to `out`.
// `header_only`: stop after the header (checking an input before a long run).
// Input errors are ParseErrors naming in.path(); output errors are left in
// out->status() (the scaler stops at the first).
// `comment_lines`: complete header lines written after OPL's own comment
// (the provenance, io/provenance_stamp.h), "" for none; "\n" line breaks,
// converted to the header's.
Status ScalePly(InputFile& in, OutputBuffer* out, double s, bool header_only,
                ScaleCounts* counts, const std::string& comment_lines);
Status ScaleXyz(InputFile& in, OutputBuffer* out, double s, bool header_only,
                ScaleCounts* counts);
Status ScaleCsv(InputFile& in, OutputBuffer* out, double s, bool header_only,
                ScaleCounts* counts);

// Shortest text that reads back exactly (std::to_chars), written at `p`
// (room for 32 bytes); returns the end.
char* WriteShortest(char* p, double v);
char* WriteShortest(char* p, float v);

// A coordinate of a text format (XYZ, points CSV) in [b, e): as
// csv_internal::ParseCoordinate (finite, |v| <= 1e12, optional leading '+'),
// without allocating. False when it is not one: the caller then asks
// ParseCoordinate for the message.
bool ParseCoordinateFast(const char* b, const char* e, double* v);

// The next line of a text input, starting at window offset *pos: [begin, end)
// without its line break ("\n"; a "\r" before it stays in the line), `next`
// where the following line starts. When the line is not all in the window,
// the *pos bytes before it are consumed and more are read (*pos becomes 0):
// offsets are always relative to in.data() after the call. Returns false at
// the end of the file. ParseError "<path>:<line>: line longer than <n> bytes"
// when a line does not fit in the buffer.
struct Line {
  size_t begin = 0, end = 0, next = 0;
};
Result<bool> NextLine(InputFile& in, size_t* pos, int64_t line_number, Line* line);

}  // namespace point_file_internal
}  // namespace opl
