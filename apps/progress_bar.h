// A one-line progress bar on stderr for long command-line runs:
//   mc [##########..........]  2300/5000  46%  4210/s  0.6 s left
// drawn only when enabled (the tools enable it when stderr is a terminal, so
// logs and pipes stay quiet), redrawn in place with '\r', erased by Finish().
#pragma once

#include <functional>

#include <chrono>
#include <string>

#include "opl/identify/identify_spots.h"

namespace opl {
namespace cli {

// True when stderr is a terminal (isatty).
bool StderrIsTerminal();

class ProgressBar {
 public:
  ProgressBar(std::string label, bool enabled);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  // Redraws the bar for `done` of `total` (rate and time left from the time
  // since construction). Does nothing when disabled.
  void Update(int done, int total);
  // Erases the bar (once); also done by the destructor.
  void Finish();
  // A progress callback (stage, done, total) for the library's long runs
  // (e.g. FrontEndOptions::progress): draws `stage`, and erases the bar when
  // any other stage reports. The bar must outlive the callback's use.
  std::function<void(const std::string&, int, int)> StageCallback(const std::string& stage);

  // A progress callback for IdentifySpots (IdentifyOptions::progress), a
  // search with no total to count towards: draws RenderIdentify's line once
  // the bar is half a second old (a quick search shows nothing), and erases
  // it when the search reports it has finished.
  std::function<void(const IdentifyProgress&)> IdentifyCallback();

  // The text of the bar (without '\r'), for tests.
  static std::string Render(const std::string& label, int done, int total, double elapsed_s);
  // The line of IdentifyCallback:
  //   identify: 37 seeds tried, 1/2 sources found, 5041/10509 points  4.1 s
  static std::string RenderIdentify(const std::string& label, const IdentifyProgress& progress,
                                    double elapsed_s);

 private:
  std::string label_;
  bool enabled_;
  void Draw(const std::string& text);
  double ElapsedSeconds() const;

  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace cli
}  // namespace opl
