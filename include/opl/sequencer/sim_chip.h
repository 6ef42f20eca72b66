// SimChip: a simulated GPIO chip for tests and dry runs.
//
// It keeps the logical state of every requested line and records every
// change (including the initial "inactive" of RequestOutputs) with a
// timestamp of the injected Clock. When `log_path` is set, each change is
// also appended at once, with one write(2), as a JSON line
//
//   {"t_ns":123456789,"offset":17,"name":"laser_a","active":true,"value":1}
//
// (t_ns: Clock time, CLOCK_MONOTONIC in the daemon; value: electrical level
// after the active-low flag) so that a test process can follow what the real
// daemon does to its lines, even after the daemon was killed.
//
// For tests of the error paths, `fail_write_number` makes exactly one
// SetActive call fail (the n-th, counted from 1 over the chip's lifetime).
#ifndef OPL_SEQUENCER_SIM_CHIP_H_
#define OPL_SEQUENCER_SIM_CHIP_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "opl/sequencer/clock.h"
#include "opl/sequencer/gpio.h"

namespace opl::sequencer {

struct SimChipOptions {
  // JSON-lines file every line change is appended to; empty: memory only.
  std::string log_path;
  // Truncate log_path when the chip is opened (else append).
  bool truncate_log = true;
  // Number of lines of the simulated chip; offsets must be below it.
  unsigned num_lines = 64;
  // 1-based index of the one SetActive call that fails with kGpioError;
  // 0: none fails.
  long fail_write_number = 0;
};

struct SimLineEvent {
  std::int64_t t_ns = 0;  // Clock time of the change
  unsigned offset = 0;
  std::string name;
  bool active = false;  // logical
  int value = 0;        // electrical, after active-low
};

class SimChip final : public GpioChip {
 public:
  // Opens (and truncates, see options) the log file if any.
  static Result<std::unique_ptr<SimChip>> Open(
      const SimChipOptions& options, std::shared_ptr<const Clock> clock);
  ~SimChip() override;

  Status RequestOutputs(const std::vector<GpioLineSpec>& lines,
                        const std::string& consumer) override;
  Status SetActive(std::size_t index, bool active) noexcept override;
  void Release() noexcept override;
  std::string Describe() const override;

  // Every change recorded so far, oldest first.
  const std::vector<SimLineEvent>& events() const { return events_; }
  // Logical state of requested line `index`; false if not requested.
  bool IsActive(std::size_t index) const;

 private:
  SimChip(const SimChipOptions& options, std::shared_ptr<const Clock> clock,
          int log_fd);
  void Record(std::size_t index) noexcept;

  SimChipOptions options_;
  std::shared_ptr<const Clock> clock_;
  int log_fd_ = -1;
  std::vector<GpioLineSpec> lines_;
  std::vector<bool> active_;
  std::vector<SimLineEvent> events_;
  long writes_ = 0;
};

// Reads a SimChip log file. A trailing partial line (a writer killed in the
// middle of a write) is ignored; any other malformed line is an error.
Result<std::vector<SimLineEvent>> ReadSimLog(const std::string& path);

}  // namespace opl::sequencer

#endif  // OPL_SEQUENCER_SIM_CHIP_H_
