// SimClock: the one mapping from a simulated flight's GPS time to host CLOCK_MONOTONIC that every
// real-time simulated stream of a run shares (the rendered cameras of sim:// and the GPS/IMU streams
// of sim/nav_stream.hpp), so frames and nav arrive in the same relation as they would in flight.
//
//   host_ns(t_gps) = host0 + (t_gps - gps0) / rate
//
// host0 is taken at the first call of anchor() (or any call that needs it), so whichever stream
// starts first starts the flight. rate 1 is real time, 4 four times faster; rate <= 0 means "as fast
// as possible": wait_until() returns at once and host_ns() is the time of the call.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>

#include "core/clock.hpp"
#include "core/conventions.hpp"

namespace augrig::sim {

class SimClock {
 public:
  SimClock(TimestampNs gps0_ns, double rate) : gps0_ns_(gps0_ns), rate_(rate) {}

  double rate() const { return rate_; }
  bool paced() const { return rate_ > 0; }

  // Fixes host0 now if nobody has yet; returns it.
  TimestampNs anchor() {
    std::call_once(once_, [this] { host0_ns_ = monotonic_now_ns(); });
    return host0_ns_;
  }

  // The host time at which GPS time t_gps_ns happens in this run.
  TimestampNs host_ns(TimestampNs t_gps_ns) {
    const TimestampNs h0 = anchor();
    if (!paced()) return monotonic_now_ns();
    return h0 + static_cast<TimestampNs>(static_cast<double>(t_gps_ns - gps0_ns_) / rate_);
  }

  // Sleeps until host_ns(t_gps_ns), in slices of at most 50 ms so that `stop` is honoured; returns
  // false when stopped first.
  bool wait_until(TimestampNs t_gps_ns, const std::atomic<bool>* stop = nullptr) {
    if (!paced()) return !(stop && *stop);
    const TimestampNs due = host_ns(t_gps_ns);
    for (;;) {
      if (stop && *stop) return false;
      const TimestampNs now = monotonic_now_ns();
      if (now >= due) return true;
      std::this_thread::sleep_for(std::chrono::nanoseconds(std::min<TimestampNs>(due - now, 50'000'000)));
    }
  }

 private:
  TimestampNs gps0_ns_;
  double rate_;
  std::once_flag once_;
  TimestampNs host0_ns_ = 0;
};

}  // namespace augrig::sim
