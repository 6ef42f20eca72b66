#include "io/point_file_stream.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>

#include "io/csv.h"

namespace opl {
namespace point_file_internal {

InputFile::~InputFile() {
  if (fd_ >= 0) ::close(fd_);
}

Status InputFile::Open(const std::string& path, size_t buffer_bytes) {
  path_ = path;
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    return Status::IoError(path + ": cannot open: " + std::strerror(errno));
  }
  if (S_ISDIR(st.st_mode)) return Status::IoError(path + ": cannot read: is a directory");
  if (!S_ISREG(st.st_mode)) {
    return Status::IoError(path + ": cannot read: not a regular file (a device, FIFO or socket)");
  }
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) return Status::IoError(path + ": cannot open: " + std::strerror(errno));
  file_size_ = static_cast<int64_t>(st.st_size);
  buffer_.reset(new char[buffer_bytes]);
  capacity_ = buffer_bytes;
  return Status::Ok();
}

Result<size_t> InputFile::Fill() {
  if (begin_ > 0) {
    std::memmove(buffer_.get(), buffer_.get() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  size_t added = 0;
  while (!eof_ && end_ < capacity_) {
    const ssize_t n = ::read(fd_, buffer_.get() + end_, capacity_ - end_);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Status::IoError(path_ + ": read error: " + std::strerror(errno));
    }
    if (n == 0) {
      eof_ = true;
      break;
    }
    end_ += static_cast<size_t>(n);
    added += static_cast<size_t>(n);
    file_offset_ += n;
  }
  if (progress && added > 0) progress(file_offset_, file_size_);
  return added;
}

Status InputFile::Ensure(size_t n) {
  while (size() < n && !eof_) {
    Result<size_t> added = Fill();
    if (!added.ok()) return added.status();
    if (*added == 0 && !eof_) break;  // buffer full
  }
  return Status::Ok();
}

OutputBuffer::OutputBuffer(AtomicFileWriter* writer, size_t buffer_bytes)
    : writer_(writer), buffer_(buffer_bytes) {}

void OutputBuffer::Flush() {
  if (size_ > 0 && writer_ != nullptr && status_.ok()) {
    status_ = writer_->Write(buffer_.data(), size_);
  }
  size_ = 0;
}

void OutputBuffer::AppendSlow(const char* p, size_t n) {
  Flush();
  if (n > buffer_.size()) {  // larger than the buffer: straight through
    if (writer_ != nullptr && status_.ok()) status_ = writer_->Write(p, n);
    return;
  }
  std::memcpy(buffer_.data(), p, n);
  size_ = n;
}

char* WriteShortest(char* p, double v) { return std::to_chars(p, p + 32, v).ptr; }
char* WriteShortest(char* p, float v) { return std::to_chars(p, p + 32, v).ptr; }

bool ParseCoordinateFast(const char* b, const char* e, double* v) {
  if (b < e && *b == '+' && e - b > 1 && b[1] != '-') ++b;
  const std::from_chars_result r = std::from_chars(b, e, *v);
  return r.ec == std::errc() && r.ptr == e && std::isfinite(*v) &&
         std::abs(*v) <= csv_internal::kMaxAbsCoordinate;
}

Result<bool> NextLine(InputFile& in, size_t* pos, int64_t line_number, Line* line) {
  while (true) {
    const char* data = in.data();
    const size_t n = in.size();
    if (*pos < n) {
      const void* nl = std::memchr(data + *pos, '\n', n - *pos);
      if (nl != nullptr) {
        line->begin = *pos;
        line->end = static_cast<size_t>(static_cast<const char*>(nl) - data);
        line->next = line->end + 1;
        return true;
      }
    }
    if (in.at_eof()) {
      if (*pos >= n) return false;
      line->begin = *pos;
      line->end = line->next = n;  // the last line, without a line break
      return true;
    }
    in.Consume(*pos);
    *pos = 0;
    Result<size_t> added = in.Fill();
    if (!added.ok()) return added.status();
    if (*added == 0 && !in.at_eof()) {
      return Status::ParseError(in.path() + ":" + std::to_string(line_number) +
                                ": line longer than " + std::to_string(in.capacity()) +
                                " bytes");
    }
  }
}

}  // namespace point_file_internal
}  // namespace opl
