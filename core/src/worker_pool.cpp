#include "worker_pool.h"

namespace msk {

WorkerPool::WorkerPool(int threads) {
  for (int t = 1; t < threads; ++t) workers_.emplace_back([this, t] { work(t); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (auto& t : workers_) t.join();
}

void WorkerPool::work(int id) {
  unsigned long seen = 0;
  for (;;) {
    const std::function<void(int, int)>* body = nullptr;
    int n = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      body = body_;
      n = n_;
    }
    const int parts = size();
    const int begin = static_cast<int>(static_cast<long long>(n) * id / parts);
    const int end = static_cast<int>(static_cast<long long>(n) * (id + 1) / parts);
    if (begin < end) (*body)(begin, end);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (--pending_ == 0) done_.notify_one();
    }
  }
}

void WorkerPool::run(int n, const std::function<void(int, int)>& body, int grain) {
  if (n <= 0) return;
  if (workers_.empty() || n < grain) {
    body(0, n);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    body_ = &body;
    n_ = n;
    pending_ = static_cast<int>(workers_.size());
    ++generation_;
  }
  wake_.notify_all();
  const int end = static_cast<int>(static_cast<long long>(n) / size());
  if (end > 0) body(0, end);
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [&] { return pending_ == 0; });
}

}  // namespace msk
