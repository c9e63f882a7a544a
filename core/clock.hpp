// The host clocks augrig reads: CLOCK_MONOTONIC (ClockDomain::kHostMonotonic), the arrival clock
// of every frame and nav input, and the CPU-time clocks that stage costs and benchmarks read. One
// reader, so every module stamps the same clock the same way.
#pragma once

#include <time.h>

#include "core/conventions.hpp"

namespace augrig {

// CLOCK_MONOTONIC now, ns (ClockDomain::kHostMonotonic).
inline TimestampNs monotonic_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<TimestampNs>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// CPU time of the calling thread, ms: a stage's cost that preemption by other threads does not inflate.
inline double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

// CPU time of the whole process (every thread, user + system), ms.
inline double process_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

}  // namespace augrig
