// Worker: one persistent thread that runs one job at a time for its owner. The augmenter hands
// it one camera's view each frame while the calling thread does the other: starting a thread per
// frame (std::async) costs tens of microseconds and starts on a cold stack, at 4 ms a frame.
#pragma once

#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace augrig {

class Worker {
 public:
  // `name`: the thread's name (core/thread_name.hpp), for top -H and bench_live.
  explicit Worker(std::string name);
  ~Worker();  // waits for the job in progress, then stops the thread
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  // Starts `job` on the worker thread. The previous job must have been waited for.
  void start(std::function<void()> job);
  // Returns when the job has finished; rethrows what it threw.
  void wait();

  // Waits for the job when a scope ends, however it ends (a job using the scope's locals must
  // not outlive them). What the job threw is dropped here: call wait() to see it.
  struct Join {
    Worker& worker;
    ~Join();
  };

 private:
  void loop();

  std::mutex mutex_;
  std::condition_variable cv_;
  std::function<void()> job_;
  bool busy_ = false, stop_ = false;
  std::exception_ptr error_;
  std::string name_;
  std::thread thread_;  // last: starts after the members it uses exist
};

}  // namespace augrig
