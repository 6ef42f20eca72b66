#include "progress_bar.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

namespace opl {
namespace cli {

bool StderrIsTerminal() { return isatty(fileno(stderr)) != 0; }

ProgressBar::ProgressBar(std::string label, bool enabled)
    : label_(std::move(label)), enabled_(enabled), start_(std::chrono::steady_clock::now()) {}

ProgressBar::~ProgressBar() { Finish(); }

std::string ProgressBar::Render(const std::string& label, int done, int total, double elapsed_s) {
  constexpr int kWidth = 24;
  const double fraction = total > 0 ? std::clamp(static_cast<double>(done) / total, 0.0, 1.0) : 1.0;
  const int filled = static_cast<int>(fraction * kWidth);
  std::string bar = label + " [" + std::string(static_cast<size_t>(filled), '#') +
                    std::string(static_cast<size_t>(kWidth - filled), '.') + "]";
  char buffer[128];
  std::snprintf(buffer, sizeof(buffer), " %d/%d %3d%%", done, total,
                static_cast<int>(std::floor(fraction * 100.0)));
  bar += buffer;
  if (done > 0 && elapsed_s > 0.0) {
    const double rate = done / elapsed_s;
    const double left = (total - done) / rate;
    std::snprintf(buffer, sizeof(buffer), "  %.0f/s  %.1f s left", rate, left);
    bar += buffer;
  }
  return bar;
}

std::string ProgressBar::RenderIdentify(const std::string& label, const IdentifyProgress& progress,
                                        double elapsed_s) {
  char buffer[200];
  std::snprintf(buffer, sizeof(buffer),
                ": %d seed%s tried, %d/%d sources found, %d/%d points  %.1f s",
                progress.seeds_tried, progress.seeds_tried == 1 ? "" : "s", progress.sources_found,
                progress.num_sources, progress.points_assigned, progress.points, elapsed_s);
  return label + buffer;
}

double ProgressBar::ElapsedSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void ProgressBar::Draw(const std::string& text) {
  // Pad to erase a longer previous line.
  std::fprintf(stderr, "\r%-78s", text.c_str());
  std::fflush(stderr);
  drawn_ = true;
}

void ProgressBar::Update(int done, int total) {
  if (!enabled_) return;
  Draw(Render(label_, done, total, ElapsedSeconds()));
}

std::function<void(const IdentifyProgress&)> ProgressBar::IdentifyCallback() {
  return [this](const IdentifyProgress& progress) {
    if (!enabled_) return;
    if (progress.finished) {
      Finish();
      return;
    }
    // Nothing for a search that is over at once (most are): only one that
    // has taken half a second is shown.
    const double elapsed = ElapsedSeconds();
    if (elapsed >= 0.5) Draw(RenderIdentify(label_, progress, elapsed));
  };
}

void ProgressBar::Finish() {
  if (!drawn_) return;
  std::fprintf(stderr, "\r%78s\r", "");
  std::fflush(stderr);
  drawn_ = false;
}

std::function<void(const std::string&, int, int)> ProgressBar::StageCallback(
    const std::string& stage) {
  return [this, stage](const std::string& reported, int done, int total) {
    if (reported == stage) {
      Update(done, total);
    } else {
      Finish();
    }
  };
}

}  // namespace cli
}  // namespace opl
