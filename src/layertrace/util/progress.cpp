#include "layertrace/util/progress.h"

#include <chrono>
#include <cstdio>

namespace lt {

Progress::Progress(std::string label, uint64_t total, bool enabled) : label_(std::move(label)), total_(total) {
  if (enabled && total_ > 0) thread_ = std::thread([this] { run(); });
}

Progress::~Progress() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
  if (printed_) std::fprintf(stderr, "\r%s: 100%%          \n", label_.c_str());
}

void Progress::run() {
  using namespace std::chrono;
  const auto start = steady_clock::now();
  std::unique_lock<std::mutex> lock(mutex_);
  while (!cv_.wait_for(lock, milliseconds(500), [this] { return stop_; })) {
    if (steady_clock::now() - start < seconds(1)) continue;
    const double pct = 100.0 * double(done_.load(std::memory_order_relaxed)) / double(total_);
    std::fprintf(stderr, "\r%s: %5.1f%%", label_.c_str(), pct);
    std::fflush(stderr);
    printed_ = true;
  }
}

}  // namespace lt
