// Progress on stderr for long runs: workers only bump an atomic counter; a
// reporter thread prints at most every half second, and only once the run has taken longer
// than a second. Silent when disabled (--quiet).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace lt {

class Progress {
 public:
  Progress(std::string label, uint64_t total, bool enabled);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void add(uint64_t n) { done_.fetch_add(n, std::memory_order_relaxed); }

 private:
  void run();
  std::string label_;
  uint64_t total_;
  std::atomic<uint64_t> done_{0};
  bool printed_ = false;
  bool stop_ = false;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::thread thread_;
};

}  // namespace lt
