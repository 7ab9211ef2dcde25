// Function multi-versioning for hot loops: the default build runs on any x86-64 (-march of the
// Release build, x86-64-v2 by default) and a function marked LT_CPU_DISPATCH gets copies
// compiled for x86-64-v3 (AVX2, FMA, BMI2) and x86-64-v4 (AVX-512 F/BW/DQ/VL/CD), the loader
// picking the best the CPU has (GCC's target_clones, resolved once by an ifunc). `flatten`
// inlines the function's callees into each copy, so the traversal it calls is compiled for the
// target too. (v4 measured: the tile capture 2–4 % faster than v3 — 16-lane depth spans — the
// HSSR march within the noise.)
//
// The copies give the same answers bit for bit: the project compiles with -ffp-contract=off
// (CMakeLists.txt), so the v3/v4 copies do not fuse multiplies and adds into FMAs (which would
// move ~0.1 % of HSSR's hits); tests compare the dispatched batch with the one-ray path.
#pragma once

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
#define LT_CPU_DISPATCH __attribute__((target_clones("default", "arch=x86-64-v3", "arch=x86-64-v4"), flatten))
#else
#define LT_CPU_DISPATCH  // other compilers and sanitizer builds: the one portable copy
#endif
