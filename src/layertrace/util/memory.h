// Memory limits: every large structure states its size before it allocates, and an
// allocation that would not fit is refused with one line naming the structure — never an
// out-of-memory kill halfway through a run, never a partial output.
#pragma once

#include <cstdint>
#include <string>

namespace lt {

/// --max-memory: the most the process may hold, in bytes (0 = no limit but the machine's).
void setMemoryLimit(uint64_t bytes);
uint64_t memoryLimit();

/// MemAvailable of /proc/meminfo, or 0 when unknown.
uint64_t availableMemoryBytes();
/// The process's resident set (/proc/self/statm), or 0 when unknown.
uint64_t residentBytes();

/// Throws InputError when `bytes` more for `what` would not fit: beyond the memory the machine
/// has available, or — with --max-memory — beyond the limit counting what the process already
/// holds. The message names `what`, its size, and the limit it breaks.
void checkAllocation(const std::string& what, uint64_t bytes);

/// "512M", "2G", "1.5G", "65536" (bytes; K, M, G, T are binary multiples, an optional trailing
/// "B" or "iB" is allowed). Throws InputError naming `option` for anything else or for 0.
uint64_t parseByteSize(const std::string& option, const std::string& text);

}  // namespace lt
