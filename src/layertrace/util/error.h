// Errors and checks.
//
// Two kinds of failure leave the library:
//   InputError    — the user gave something we cannot use (a file, a value, an option).
//                   The CLI prints its one-line message and exits with status 2.
//   InternalError — a broken invariant inside layertrace. The CLI exits with status 1.
// Library code never calls exit(); it throws, and main() decides.
//
// Checks come in two tiers: LT_CHECK(cond, ...) is always on and prints the values involved;
// LT_DCHECK is for hot loops and only exists in debug builds.
//
// Layer: util/ is the bottom layer — errors and checks, image I/O, progress, timing. It knows
// no scene and includes nothing of layertrace outside util/.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace lt {

struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct InternalError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Concatenates anything streamable into one string: cat("width ", w, " too large").
template <typename... Args>
std::string cat(const Args&... args) {
  std::ostringstream s;
  (s << ... << args);
  return s.str();
}

template <typename... Args>
[[noreturn]] void inputError(const Args&... args) {
  throw InputError(cat(args...));
}

}  // namespace lt

#define LT_CHECK(cond, ...)                                                                   \
  do {                                                                                        \
    if (!(cond))                                                                              \
      throw ::lt::InternalError(::lt::cat(__FILE__, ":", __LINE__, ": check failed: " #cond " " \
                                          __VA_OPT__(, ) __VA_ARGS__));                       \
  } while (0)

#ifndef NDEBUG
#define LT_DCHECK(cond, ...) LT_CHECK(cond, ##__VA_ARGS__)
#else
#define LT_DCHECK(cond, ...) ((void)0)
#endif
