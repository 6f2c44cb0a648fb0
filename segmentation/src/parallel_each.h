#pragma once
// Independent items run on several threads: each item's work reads shared inputs and writes only its own outputs, so
// the result is the same for any number of threads.
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace msk::detail {

/// The threads a `threads` setting means: itself if positive, else all cores (at least 1).
inline int threadCount(int threads) {
  return threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

/// Calls work(k) for every k in [0, n) on `threads` threads (0 = all cores; the caller is one of them), handing the
/// items out one at a time. Once all threads have stopped, the exception of the lowest item that threw is rethrown (the
/// one a single thread would have met first).
template <typename Work>
void parallelEach(size_t n, int threads, Work&& work) {
  const size_t workers = std::min(n, static_cast<size_t>(threadCount(threads)));
  if (workers <= 1) {
    for (size_t k = 0; k < n; ++k) work(k);
    return;
  }
  std::atomic<size_t> next{0};
  std::exception_ptr failure;
  size_t failedItem = n;
  std::mutex failureMutex;
  auto loop = [&]() {
    for (size_t k = next++; k < n; k = next++) {
      try {
        work(k);
      } catch (...) {
        std::lock_guard<std::mutex> lock(failureMutex);
        if (k < failedItem) {
          failure = std::current_exception();
          failedItem = k;
        }
      }
    }
  };
  std::vector<std::thread> pool;
  for (size_t t = 1; t < workers; ++t) pool.emplace_back(loop);
  loop();
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
}

}  // namespace msk::detail
