// Internal: a plain parallel loop for the library's independent jobs (the
// front end's per-image detection, the calibration's shared-error re-solves).
//
// job(0) .. job(count - 1) run on min(threads, count) worker threads that take
// indices from a shared counter; with threads <= 1 or count <= 1 they run in
// order on the calling thread. Each job must depend on its index only and
// store its result at that index, so that the outcome does not depend on the
// number of threads. Jobs must not throw.
#pragma once

#include <functional>

namespace opl::internal {

void ParallelFor(int count, int threads, const std::function<void(int)>& job);

}  // namespace opl::internal
