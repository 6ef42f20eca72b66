// libgpiod 1.6 backend of GpioChip (Debian 12). See gpio.h for how a 2.x
// backend maps onto the same interface.
#include <gpiod.h>

#include <cerrno>
#include <cstring>
#include <utility>
#include <vector>

#include "opl/sequencer/gpio.h"

namespace opl::sequencer {
namespace {

std::string ErrnoText(int err) { return std::strerror(err); }

class GpiodChip final : public GpioChip {
 public:
  GpiodChip(gpiod_chip* chip, std::string name) : chip_(chip), name_(std::move(name)) {}
  ~GpiodChip() override {
    Release();
    if (chip_ != nullptr) gpiod_chip_close(chip_);
  }

  Status RequestOutputs(const std::vector<GpioLineSpec>& specs, const std::string& consumer) override {
    if (!lines_.empty()) return Status(StatusCode::kFailedPrecondition, "gpiod: lines already requested on " + name_);
    const unsigned num_lines = gpiod_chip_num_lines(chip_);
    std::vector<gpiod_line*> lines;
    for (const GpioLineSpec& spec : specs) {
      const std::string what = "line " + std::to_string(spec.offset) + " (" + spec.name + ") of " + name_;
      if (spec.offset >= num_lines) {
        Drop(&lines);
        return Status(StatusCode::kNotFound, what + ": the chip has " + std::to_string(num_lines) + " lines");
      }
      gpiod_line* line = gpiod_chip_get_line(chip_, spec.offset);
      if (line == nullptr) {
        const int err = errno;
        Drop(&lines);
        return Status(StatusCode::kGpioError, what + ": " + ErrnoText(err));
      }
      const int flags = spec.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
      // default_val is logical: 0 = inactive = laser off from the first instant.
      if (gpiod_line_request_output_flags(line, consumer.c_str(), flags, 0) != 0) {
        const int err = errno;
        Drop(&lines);
        return Status(StatusCode::kGpioError, what + ": request as output failed: " + ErrnoText(err));
      }
      lines.push_back(line);
    }
    lines_ = std::move(lines);
    specs_ = specs;
    return Status::Ok();
  }

  Status SetActive(std::size_t index, bool active) noexcept override {
    if (index >= lines_.size()) return Status(StatusCode::kInvalidArgument, "gpiod: no requested line at index " + std::to_string(index));
    if (gpiod_line_set_value(lines_[index], active ? 1 : 0) != 0) {
      const int err = errno;
      try {
        return Status(StatusCode::kGpioError, "gpiod: set line " + std::to_string(specs_[index].offset) + " (" +
                                                  specs_[index].name + ") of " + name_ + " to " +
                                                  (active ? "active" : "inactive") + ": " + ErrnoText(err));
      } catch (...) {
        return Status(StatusCode::kGpioError, std::string());
      }
    }
    return Status::Ok();
  }

  void Release() noexcept override { Drop(&lines_); }

  std::string Describe() const override { return "gpiod:" + name_; }

 private:
  static void Drop(std::vector<gpiod_line*>* lines) noexcept {
    for (gpiod_line* line : *lines) gpiod_line_release(line);
    lines->clear();
  }

  gpiod_chip* chip_;
  std::string name_;
  std::vector<gpiod_line*> lines_;
  std::vector<GpioLineSpec> specs_;
};

}  // namespace

Result<std::unique_ptr<GpioChip>> OpenGpiodChip(const std::string& chip) {
  if (chip.empty()) return Status(StatusCode::kInvalidArgument, "gpiod: empty chip name");
  errno = 0;
  gpiod_chip* handle = gpiod_chip_open_lookup(chip.c_str());
  if (handle == nullptr) {
    const int err = errno;
    return Status(err == ENOENT || err == 0 ? StatusCode::kNotFound : StatusCode::kGpioError,
                  "gpiod: cannot open chip '" + chip + "': " + (err == 0 ? std::string("no such chip") : ErrnoText(err)));
  }
  std::string name = gpiod_chip_name(handle) != nullptr ? gpiod_chip_name(handle) : chip;
  return std::unique_ptr<GpioChip>(new GpiodChip(handle, std::move(name)));
}

}  // namespace opl::sequencer
