#include "layertrace/util/memory.h"

#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>

#include "layertrace/util/error.h"

namespace lt {

namespace {

std::atomic<uint64_t> gLimit{0};

std::string mib(uint64_t bytes) { return bytes < (1u << 20) ? cat(bytes, " bytes") : cat((bytes + (1u << 20) - 1) >> 20, " MiB"); }

}  // namespace

void setMemoryLimit(uint64_t bytes) { gLimit = bytes; }
uint64_t memoryLimit() { return gLimit; }

uint64_t availableMemoryBytes() {
  std::ifstream in("/proc/meminfo");
  std::string key, unit;
  uint64_t value = 0;
  while (in >> key >> value >> unit)
    if (key == "MemAvailable:") return value * 1024;
  return 0;
}

uint64_t residentBytes() {
  std::ifstream in("/proc/self/statm");
  uint64_t size = 0, resident = 0;
  if (!(in >> size >> resident)) return 0;
  return resident * uint64_t(sysconf(_SC_PAGESIZE));
}

void checkAllocation(const std::string& what, uint64_t bytes) {
  if (const uint64_t limit = gLimit; limit) {
    const uint64_t held = residentBytes();
    if (bytes > limit || held > limit - bytes)
      inputError("--max-memory ", mib(limit), ": ", what, " needs ", mib(bytes), " more (the process holds ", mib(held), ")");
  }
  const uint64_t available = availableMemoryBytes();
  if (available && bytes > available) inputError(what, " needs ", mib(bytes), ", only ", mib(available), " of memory available");
}

uint64_t parseByteSize(const std::string& option, const std::string& text) {
  const char* s = text.c_str();
  char* end = nullptr;
  const double value = std::strtod(s, &end);
  std::string unit(end);
  for (char& c : unit) c = char(std::toupper(static_cast<unsigned char>(c)));
  if (unit.size() > 1 && unit.back() == 'B') unit.pop_back();
  if (unit.size() > 1 && unit.back() == 'I') unit.pop_back();
  int shift = 0;
  if (unit == "K") shift = 10;
  else if (unit == "M") shift = 20;
  else if (unit == "G") shift = 30;
  else if (unit == "T") shift = 40;
  else if (!unit.empty() && unit != "B") inputError(option, " ", text, ": not a size (use e.g. 512M, 2G or bytes)");
  const double bytes = value * std::ldexp(1.0, shift);
  if (end == s || !std::isfinite(value) || !(bytes >= 1.0) || bytes > 1.8e19)
    inputError(option, " ", text, ": not a size (use e.g. 512M, 2G or bytes)");
  return uint64_t(bytes);
}

}  // namespace lt
