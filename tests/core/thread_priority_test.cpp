// lower_thread_priority(): the calling thread's nice value goes up, capped at 19, and only its own:
// the thread that started it (and the process as `ps` shows it) keeps its value.
#include "core/thread_priority.hpp"

#include <thread>

#include <gtest/gtest.h>

namespace augrig {
namespace {

int nice_of_this_thread() {
  return getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
}

TEST(ThreadPriority, LowersTheCallingThreadOnly) {
  const int before = nice_of_this_thread();
  int in_thread = -1000, seen = -1000, capped = -1000, seen_capped = -1000;
  std::thread t([&] {
    in_thread = lower_thread_priority(10);
    seen = nice_of_this_thread();
    capped = lower_thread_priority(19);  // beyond 19: 19
    seen_capped = nice_of_this_thread();
  });
  t.join();
  EXPECT_EQ(in_thread, std::min(19, before + 10));
  EXPECT_EQ(seen, in_thread);
  EXPECT_EQ(capped, 19);
  EXPECT_EQ(seen_capped, 19);
  EXPECT_EQ(nice_of_this_thread(), before);  // the caller's own thread untouched
}

TEST(ThreadPriority, IncrementsOutsideOneToNineteenAreClamped) {
  const int before = nice_of_this_thread();
  int zero = -1000, negative = -1000;
  std::thread t([&] {
    zero = lower_thread_priority(0);       // at least 1: never raises priority
    negative = lower_thread_priority(-5);  // likewise
  });
  t.join();
  EXPECT_EQ(zero, std::min(19, before + 1));
  EXPECT_EQ(negative, std::min(19, before + 2));
}

}  // namespace
}  // namespace augrig
