// Status and Result<T>: how every call of the sequencer library reports
// failure. Nothing in the library throws across its API, aborts or exits;
// a call that can fail returns a Status (or a Result<T> that carries one),
// and the daemon maps failures to the exit codes documented in
// docs/sequencer.md.
//
//   Result<SequencerConfig> config = LoadConfig(path);
//   if (!config.ok()) { std::cerr << config.status().ToString(); return 3; }
//   Use(config.value());
#ifndef OPL_SEQUENCER_STATUS_H_
#define OPL_SEQUENCER_STATUS_H_

#include <optional>
#include <string>
#include <utility>

namespace opl::sequencer {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,     // a request or configuration value is wrong
  kFailedPrecondition,  // the request is valid but not in the current state
  kNotFound,            // a file, chip or line does not exist
  kIoError,             // a file or socket operation failed
  kGpioError,           // a GPIO request or write failed
  kInternal,            // a bug or an unexpected system failure
};

const char* StatusCodeName(StatusCode code) noexcept;

class Status {
 public:
  Status() = default;  // OK
  Status(StatusCode code, std::string message)
      : code_(code), message_(std::move(message)) {}
  static Status Ok() { return Status(); }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "GPIO_ERROR: set line 17 (laser_a): Device or resource busy".
  std::string ToString() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

// A value or the Status that says why there is none.
template <typename T>
class Result {
 public:
  Result(T value) : value_(std::move(value)) {}  // NOLINT: implicit by design
  Result(Status status) : status_(std::move(status)) {  // NOLINT
    if (status_.ok()) status_ = Status(StatusCode::kInternal, "Result built from an OK status without a value");
  }
  bool ok() const { return status_.ok(); }
  const Status& status() const { return status_; }
  // Precondition: ok().
  T& value() & { return *value_; }
  const T& value() const& { return *value_; }
  T&& value() && { return std::move(*value_); }

 private:
  Status status_;
  std::optional<T> value_;
};

}  // namespace opl::sequencer

#endif  // OPL_SEQUENCER_STATUS_H_
