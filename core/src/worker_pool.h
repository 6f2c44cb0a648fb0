#pragma once
/// A small fixed pool of threads for the solvers' parallel loops (private to msk_core).
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace msk {

/// Runs a loop body over [0, n) split into one contiguous chunk per thread (chunk t on thread t, the caller being
/// thread 0). Loops below `grain` items run on the caller alone. Bodies must not throw.
class WorkerPool {
 public:
  /// `threads` ≥ 1 (1 = no extra thread).
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;
  /// Number of threads, the caller included.
  int size() const { return static_cast<int>(workers_.size()) + 1; }
  /// Calls body(begin, end) on disjoint chunks covering [0, n); returns when all are done.
  void run(int n, const std::function<void(int, int)>& body, int grain = 512);

 private:
  void work(int id);
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(int, int)>* body_ = nullptr;
  int n_ = 0, pending_ = 0;
  unsigned long generation_ = 0;
  bool stop_ = false;
};

}  // namespace msk
