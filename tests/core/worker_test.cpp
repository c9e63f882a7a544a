#include "core/worker.hpp"

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <pthread.h>

namespace augrig {
namespace {

TEST(Worker, RunsEachJobOnItsOwnThreadAndWaitReturnsAfterIt) {
  Worker w("augrig-test");
  const std::thread::id caller = std::this_thread::get_id();
  std::thread::id ran_on;
  std::vector<int> done;
  for (int i = 0; i < 200; ++i) {
    w.start([&, i] {
      ran_on = std::this_thread::get_id();
      done.push_back(i);  // the caller does not touch `done` until wait() returns
    });
    w.wait();
    ASSERT_EQ(done.size(), static_cast<std::size_t>(i + 1));
    ASSERT_EQ(done.back(), i);
  }
  EXPECT_NE(ran_on, caller);
}

TEST(Worker, ThreadKeepsItsIdentityAndName) {
  Worker w("augrig-view");
  std::thread::id first, later;
  char name[16] = {};
  w.start([&] {
    first = std::this_thread::get_id();
    pthread_getname_np(pthread_self(), name, sizeof name);
  });
  w.wait();
  w.start([&] { later = std::this_thread::get_id(); });
  w.wait();
  EXPECT_EQ(first, later);  // one persistent thread, not one per job
  EXPECT_STREQ(name, "augrig-view");
}

TEST(Worker, JobsOverlapTheCallersWork) {
  Worker w("augrig-test");
  std::atomic<bool> caller_waiting{false}, worker_saw_it{false};
  w.start([&] {
    // Spins until the caller, having started this job, runs its own work: both run at once. A
    // job run inside start() would see nothing for 5 s.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (!caller_waiting && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
    worker_saw_it = caller_waiting.load();
  });
  caller_waiting = true;
  w.wait();
  EXPECT_TRUE(worker_saw_it);
}

TEST(Worker, WaitRethrowsWhatTheJobThrewAndTheWorkerGoesOn) {
  Worker w("augrig-test");
  w.start([] { throw std::runtime_error("job failed"); });
  EXPECT_THROW(w.wait(), std::runtime_error);
  int ran = 0;
  w.start([&] { ran = 1; });
  EXPECT_NO_THROW(w.wait());
  EXPECT_EQ(ran, 1);
}

TEST(Worker, JoinWaitsWhenItsScopeEndsEvenByAnException) {
  Worker w("augrig-test");
  std::atomic<bool> finished{false};
  try {
    w.start([&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      finished = true;
    });
    const Worker::Join join{w};
    throw std::runtime_error("the caller's own work failed");
  } catch (const std::runtime_error&) {
    EXPECT_TRUE(finished);  // the job was over before the scope's locals went
  }
}

TEST(Worker, DestructorWaitsForTheJobInProgress) {
  std::atomic<bool> finished{false};
  {
    Worker w("augrig-test");
    w.start([&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      finished = true;
    });
  }  // no wait(): the destructor must not cut the job short
  EXPECT_TRUE(finished);
}

}  // namespace
}  // namespace augrig
