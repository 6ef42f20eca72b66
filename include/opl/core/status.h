// Status and Result<T>: how every public OPL call reports failure.
//
// Nothing in the library aborts, exits or throws across the API on bad input:
// a call returns a Status (or a Result<T> holding either a value or a Status)
// whose message is one line naming the input and what is wrong with it, e.g.
//   "spots.csv:14: field 'x': not a number: 'abc'"
// CLIs map Status codes to documented exit codes (see apps/).
#pragma once

#include <optional>
#include <string>
#include <utility>

namespace opl {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,  // a value given by the caller is out of its domain
  kIoError,          // a file could not be read or written
  kParseError,       // a file's content is malformed (names file and line)
  kNoSolution,       // the data are valid but do not determine an answer
};

const char* StatusCodeName(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;  // OK
  Status(StatusCode code, std::string message)
      : code_(code), message_(std::move(message)) {}

  static Status Ok() { return Status(); }
  static Status InvalidArgument(std::string m) {
    return {StatusCode::kInvalidArgument, std::move(m)};
  }
  static Status IoError(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
  static Status ParseError(std::string m) {
    return {StatusCode::kParseError, std::move(m)};
  }
  static Status NoSolution(std::string m) {
    return {StatusCode::kNoSolution, std::move(m)};
  }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "<CodeName>: <message>", or "OK".
  std::string ToString() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

// Either a value or a non-OK Status.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}  // NOLINT: implicit by design
  Result(Status status) : status_(std::move(status)) {  // NOLINT
    if (status_.ok()) status_ = Status(StatusCode::kInvalidArgument,
                                       "Result constructed from an OK status without a value");
  }

  bool ok() const { return value_.has_value(); }
  const Status& status() const { return status_; }
  const T& value() const& { return *value_; }
  T& value() & { return *value_; }
  T&& value() && { return std::move(*value_); }
  const T& operator*() const& { return *value_; }
  T& operator*() & { return *value_; }
  const T* operator->() const { return &*value_; }
  T* operator->() { return &*value_; }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace opl

// Returns from the enclosing function if `expr` (a Status) is not OK.
#define OPL_RETURN_IF_ERROR(expr)          \
  do {                                     \
    ::opl::Status _opl_status = (expr);    \
    if (!_opl_status.ok()) return _opl_status; \
  } while (0)
