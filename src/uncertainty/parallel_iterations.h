// Internal to src/uncertainty: the thread pool of the Monte Carlo runs
// (monte_carlo.cc, calibration_monte_carlo.cc).
//
// Iterations 0 .. m-1 run on a pool of worker threads that take indices from a
// shared atomic counter; every result is stored at its index, so the caller
// reduces them in index order and the outcome does not depend on the number of
// threads nor on the scheduling (each iteration must depend on its index only,
// e.g. draw from a generator seeded with IterationSeed(seed, i)).
//
// Progress: progress(done, m) is called on the calling thread about every
// progress_interval_s while the workers run, and once at the end with
// done = m (never from a worker thread, so the callback needs no locking).
// A callback that throws is not called again.
//
// Exceptions: an exception thrown by an iteration is caught on its worker and
// turned into that iteration's result by on_exception(i, what) (when that
// throws too, the result stays R(): R's default value should read as a
// failure). Nothing is thrown out of RunIterations, and a failure to start a
// thread (std::system_error) only means fewer workers: with none at all the
// calling thread runs every iteration itself.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace opl::internal {

using IterationProgress = std::function<void(int done, int total)>;

// The number of worker threads RunIterations uses for `requested` (0: every
// core, std::thread::hardware_concurrency(), at least 1) and m iterations:
// never more than m, at least 1 (0 when m <= 0).
int IterationThreads(int requested, int m);

// Runs body(i) for every i in [0, m) as described above. body must only write
// state of its own index. on_exception(i, what) is called, on the worker, for
// an iteration that threw. Returns the number of worker threads that ran
// (0 when the calling thread ran everything, or m <= 0).
int ParallelForIterations(int m, int threads, const std::function<void(int)>& body,
                          const std::function<void(int, const std::string&)>& on_exception,
                          const IterationProgress& progress, double progress_interval_s);

// out->at(i) = f(i) for every i in [0, m) (out is resized to m, every element
// first reset to R()); see the header comment. Returns the worker threads that
// ran.
template <class R>
int RunIterations(int m, int threads, const std::function<R(int)>& f,
                  const std::function<R(int, const std::string&)>& on_exception,
                  std::vector<R>* out, const IterationProgress& progress,
                  double progress_interval_s) {
  out->assign(static_cast<size_t>(m > 0 ? m : 0), R());
  return ParallelForIterations(
      m, threads, [&](int i) { (*out)[static_cast<size_t>(i)] = f(i); },
      [&](int i, const std::string& what) { (*out)[static_cast<size_t>(i)] = on_exception(i, what); },
      progress, progress_interval_s);
}

}  // namespace opl::internal
