#include "uncertainty/parallel_iterations.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <system_error>
#include <thread>

namespace opl::internal {

int IterationThreads(int requested, int m) {
  if (m <= 0) return 0;
  int threads = requested;
  if (threads <= 0) threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  return std::min(threads, m);
}

int ParallelForIterations(int m, int threads, const std::function<void(int)>& body,
                          const std::function<void(int, const std::string&)>& on_exception,
                          const IterationProgress& progress, double progress_interval_s) {
  if (m <= 0) return 0;
  threads = IterationThreads(threads, m);
  std::atomic<int> next{0};
  std::atomic<int> done{0};
  std::mutex mutex;
  std::condition_variable all_done;
  auto report_exception = [&](int i, const char* what) {
    if (!on_exception) return;
    try {
      on_exception(i, what);
    } catch (...) {
      // The result of iteration i stays as it was (R(): a failure).
    }
  };
  auto worker = [&]() {
    for (;;) {
      const int i = next.fetch_add(1);
      if (i >= m) break;
      try {
        body(i);
      } catch (const std::exception& e) {
        report_exception(i, e.what());
      } catch (...) {
        report_exception(i, "unknown exception");
      }
      if (done.fetch_add(1) + 1 == m) {
        std::lock_guard<std::mutex> lock(mutex);
        all_done.notify_all();
      }
    }
  };
  // A progress callback that throws is not called again (the workers must
  // still be joined).
  bool progress_ok = static_cast<bool>(progress);
  auto call_progress = [&](int d) {
    if (!progress_ok) return;
    try {
      progress(d, m);
    } catch (...) {
      progress_ok = false;
    }
  };
  std::vector<std::thread> pool;
  try {
    pool.reserve(static_cast<size_t>(threads));
    for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  } catch (const std::exception&) {
    // std::system_error (no more threads) or bad_alloc: go on with the workers
    // that started, or on the calling thread.
  }
  if (pool.empty()) {
    worker();
  } else if (progress_ok) {
    const auto interval = std::chrono::duration<double>(progress_interval_s);
    std::unique_lock<std::mutex> lock(mutex);
    while (progress_ok &&
           !all_done.wait_for(lock, interval, [&] { return done.load() >= m; })) {
      const int d = done.load();
      lock.unlock();
      call_progress(d);
      lock.lock();
    }
  }
  for (std::thread& t : pool) t.join();
  call_progress(m);
  return static_cast<int>(pool.size());
}

}  // namespace opl::internal
