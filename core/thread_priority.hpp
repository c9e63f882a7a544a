// lower_thread_priority(): the calling thread, and it alone, gives way to the others (Linux: each
// thread has its own nice value). The live view's coders (augrig-jpeg, augrig-h264) run at +10 so
// that the pipeline, the window and the recorder are never kept waiting for a core by them: on a
// busy machine a coder falls behind and drops frames for its own topics (counted), and the frames
// the pipeline draws and records keep their latency. Raising one's nice value needs no privilege.
// Not SCHED_IDLE: tried, it starved the coders outright beside two CPU-bound processes (no frame
// coded in 10 s), and bench_live showed no gain over nice +10 beyond the machine's noise.
#pragma once

#include <algorithm>
#include <cerrno>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace augrig {

// Adds `nice_increment` (1..19) to the calling thread's nice value, at most 19; returns the value it
// has now, or -100 where the system refused (the thread then runs as before).
inline int lower_thread_priority(int nice_increment) {
  const auto tid = static_cast<id_t>(syscall(SYS_gettid));
  errno = 0;
  const int now = getpriority(PRIO_PROCESS, tid);
  if (now == -1 && errno != 0) return -100;
  const int want = std::min(19, now + std::clamp(nice_increment, 1, 19));
  if (setpriority(PRIO_PROCESS, tid, want) != 0) return -100;
  return want;
}

}  // namespace augrig
