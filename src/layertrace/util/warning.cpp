#include "layertrace/util/warning.h"

#include <iostream>
#include <mutex>

namespace lt {
namespace {

std::mutex& warningMutex() {
  static std::mutex m;
  return m;
}

WarningSink& currentSink() {
  static WarningSink sink;
  return sink;
}

}  // namespace

void warning(const std::string& message) {
  const std::lock_guard lock(warningMutex());
  if (currentSink()) return currentSink()(message);
  std::cerr << "layertrace: warning: " << message << '\n';
}

WarningSink setWarningSink(WarningSink sink) {
  const std::lock_guard lock(warningMutex());
  std::swap(currentSink(), sink);
  return sink;
}

}  // namespace lt
