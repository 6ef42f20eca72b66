#include "opl/sequencer/sim_chip.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <utility>

#include <nlohmann/json.hpp>

namespace opl::sequencer {
namespace {

std::string Errno(const std::string& what) { return what + ": " + std::strerror(errno); }

}  // namespace

Result<std::unique_ptr<SimChip>> SimChip::Open(const SimChipOptions& options,
                                               std::shared_ptr<const Clock> clock) {
  if (!clock) return Status(StatusCode::kInvalidArgument, "sim chip: no clock");
  int fd = -1;
  if (!options.log_path.empty()) {
    int flags = O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC;
    if (options.truncate_log) flags |= O_TRUNC;
    fd = ::open(options.log_path.c_str(), flags, 0644);
    if (fd < 0) return Status(StatusCode::kIoError, Errno("sim chip: open log '" + options.log_path + "'"));
  }
  return std::unique_ptr<SimChip>(new SimChip(options, std::move(clock), fd));
}

SimChip::SimChip(const SimChipOptions& options, std::shared_ptr<const Clock> clock, int log_fd)
    : options_(options), clock_(std::move(clock)), log_fd_(log_fd) {}

SimChip::~SimChip() {
  Release();
  if (log_fd_ >= 0) ::close(log_fd_);
}

Status SimChip::RequestOutputs(const std::vector<GpioLineSpec>& lines, const std::string& consumer) {
  if (!lines_.empty()) return Status(StatusCode::kFailedPrecondition, "sim chip: lines already requested");
  if (consumer.empty()) return Status(StatusCode::kInvalidArgument, "sim chip: empty consumer");
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].offset >= options_.num_lines) {
      return Status(StatusCode::kNotFound, "sim chip: line " + std::to_string(lines[i].offset) + " (" +
                                               lines[i].name + ") beyond the chip's " +
                                               std::to_string(options_.num_lines) + " lines");
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (lines[j].offset == lines[i].offset) {
        return Status(StatusCode::kGpioError, "sim chip: line " + std::to_string(lines[i].offset) + " requested twice");
      }
    }
  }
  lines_ = lines;
  active_.assign(lines.size(), false);
  for (std::size_t i = 0; i < lines_.size(); ++i) Record(i);
  return Status::Ok();
}

Status SimChip::SetActive(std::size_t index, bool active) noexcept {
  if (index >= lines_.size()) return Status(StatusCode::kInvalidArgument, "sim chip: no requested line at index " + std::to_string(index));
  ++writes_;
  if (options_.fail_write_number > 0 && writes_ == options_.fail_write_number) {
    return Status(StatusCode::kGpioError, "sim chip: injected failure of write " + std::to_string(writes_) + " (line " +
                                              std::to_string(lines_[index].offset) + ", " + lines_[index].name + ")");
  }
  active_[index] = active;
  Record(index);
  return Status::Ok();
}

void SimChip::Record(std::size_t index) noexcept {
  SimLineEvent e;
  e.t_ns = clock_->NowNs();
  e.offset = lines_[index].offset;
  e.active = active_[index];
  e.value = (e.active != lines_[index].active_low) ? 1 : 0;
  try {
    e.name = lines_[index].name;
    events_.push_back(e);
    if (log_fd_ >= 0) {
      // One write(2) per line: a reader never sees half a record unless the
      // process dies inside write().
      std::string line = "{\"t_ns\":" + std::to_string(e.t_ns) + ",\"offset\":" + std::to_string(e.offset) +
                         ",\"name\":" + nlohmann::json(e.name).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) +
                         ",\"active\":" + (e.active ? "true" : "false") + ",\"value\":" + std::to_string(e.value) + "}\n";
      ssize_t n = ::write(log_fd_, line.data(), line.size());
      (void)n;  // a failed log write must not change what the lines do
    }
  } catch (...) {
    // Out of memory while recording: the line state is still right.
  }
}

void SimChip::Release() noexcept {
  lines_.clear();
  active_.clear();
}

std::string SimChip::Describe() const {
  return "sim:" + (options_.log_path.empty() ? std::string("(memory)") : options_.log_path);
}

bool SimChip::IsActive(std::size_t index) const { return index < active_.size() && active_[index]; }

Result<std::vector<SimLineEvent>> ReadSimLog(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status(StatusCode::kNotFound, "sim log '" + path + "' cannot be opened");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  std::vector<SimLineEvent> events;
  std::size_t pos = 0;
  int line_number = 0;
  while (pos < text.size()) {
    std::size_t nl = text.find('\n', pos);
    if (nl == std::string::npos) break;  // partial last line: ignored
    ++line_number;
    const std::string line = text.substr(pos, nl - pos);
    pos = nl + 1;
    try {
      nlohmann::json j = nlohmann::json::parse(line);
      SimLineEvent e;
      e.t_ns = j.at("t_ns").get<std::int64_t>();
      e.offset = j.at("offset").get<unsigned>();
      e.name = j.at("name").get<std::string>();
      e.active = j.at("active").get<bool>();
      e.value = j.at("value").get<int>();
      events.push_back(std::move(e));
    } catch (const std::exception& ex) {
      return Status(StatusCode::kInvalidArgument,
                    "sim log '" + path + "' line " + std::to_string(line_number) + ": " + ex.what());
    }
  }
  return events;
}

}  // namespace opl::sequencer
