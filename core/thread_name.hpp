// set_thread_name(): names the calling thread (Linux: 15 characters at most, longer names are cut),
// so that top -H, /proc/PID/task/*/comm and bench/bench_live can tell augrig's threads apart:
//   augrig-cap0/1   a camera's capture thread (a sim:// source renders its frames there)
//   augrig-pipe     the pipeline (nav pose, augmentation, statistics) when a window is open
//   augrig-rec*     the recorder's compression workers, writer and checkpointer
//   augrig-nav      a live nav input;  augrig-simnav  the simulated nav streams
//   augrig-jpeg, augrig-h264  the live view's coders (at nice +10: core/thread_priority.hpp)
#pragma once

#include <string>

#include <pthread.h>

namespace augrig {

inline void set_thread_name(const std::string& name) {
  pthread_setname_np(pthread_self(), name.substr(0, 15).c_str());
}

}  // namespace augrig
