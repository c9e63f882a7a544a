// The host clocks augrig reads: CLOCK_MONOTONIC (ClockDomain::kHostMonotonic), the arrival clock
// of every frame and nav input. One reader, so every module stamps the same clock the same way.
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

}  // namespace augrig
