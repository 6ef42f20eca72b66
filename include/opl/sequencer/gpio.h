// The GPIO layer: a thin interface over a chip's output lines, with two
// backends, libgpiod (OpenGpiodChip, libgpiod 1.6 C API as shipped by
// Debian 12) and a simulated chip that records every change (sim_chip.h).
//
// Model: a chip is opened, a fixed set of lines is requested as outputs once
// (RequestOutputs), and afterwards each line is addressed by its index in that
// request. Values are *logical*: active = true means "laser on", "blocker
// closed", "trigger asserted"; the backend applies the line's active-low flag
// (libgpiod does it in the kernel with GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW).
//
// Contract:
//  - RequestOutputs drives every line inactive as part of the request, so a
//    freshly requested chip has every laser off. On failure nothing stays
//    requested.
//  - SetActive never throws; a failure is returned and the caller (the
//    Sequencer) then drives every line off.
//  - Release (and the destructor) give the lines back to the kernel. The
//    kernel then keeps the last driven value on most controllers: the caller
//    drives everything off before releasing (see docs/sequencer.md, Safety).
//
// Porting to libgpiod 2.x needs a second implementation of this interface
// only: RequestOutputs maps to gpiod_chip_request_lines() with one
// gpiod_line_settings per line (direction output, active-low, output value
// inactive), SetActive to gpiod_line_request_set_value().
#ifndef OPL_SEQUENCER_GPIO_H_
#define OPL_SEQUENCER_GPIO_H_

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "opl/sequencer/status.h"

namespace opl::sequencer {

struct GpioLineSpec {
  unsigned offset = 0;      // line offset on the chip
  bool active_low = false;  // true: active (on) is the low electrical level
  std::string name;         // role name, for messages and logs ("laser_a")
};

class GpioChip {
 public:
  virtual ~GpioChip() = default;
  // Requests every line of `lines` as an output driven inactive. `consumer`
  // is the label the kernel shows for the lines (gpioinfo).
  virtual Status RequestOutputs(const std::vector<GpioLineSpec>& lines,
                                const std::string& consumer) = 0;
  // Drives line `index` (position in the RequestOutputs vector) to logical
  // `active`.
  virtual Status SetActive(std::size_t index, bool active) noexcept = 0;
  // Gives every requested line back. Idempotent.
  virtual void Release() noexcept = 0;
  // "gpiod:gpiochip0" or "sim:/tmp/x.jsonl", for messages.
  virtual std::string Describe() const = 0;
};

// Opens a GPIO chip with libgpiod 1.6. `chip` is anything
// gpiod_chip_open_lookup accepts: "gpiochip0", "/dev/gpiochip0", a chip label
// or a number.
Result<std::unique_ptr<GpioChip>> OpenGpiodChip(const std::string& chip);

}  // namespace opl::sequencer

#endif  // OPL_SEQUENCER_GPIO_H_
