// Real GigE Vision peers for capture tests: Aravis' fake GV camera, either inside the test process
// (FakeGvCamera: serves the frames a test hands it, bit for bit, through GVCP/GVSP on loopback) or
// as the separate arv-fake-gv-camera-0.8 program (FakeGvProcess: a process a test can kill).
#pragma once

#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include <sys/types.h>

#include "core/image.hpp"

typedef struct _ArvGvFakeCamera ArvGvFakeCamera;
typedef struct _ArvBuffer ArvBuffer;

namespace augrig::test {

// Gives loopback a further address (127.0.0.2 for a second camera) when it lacks it; needs root.
// Returns false with `why` when the address is absent and cannot be added.
bool ensure_loopback_address(const std::string& address, std::string* why);

// One image the fake camera sends, with the device timestamp it puts in the GVSP leader.
struct ServedFrame {
  Image image;
  std::uint64_t timestamp_ns = 0;
};

class FakeGvCamera {
 public:
  // Starts serving GVCP on `address` (an address of a local interface). Check running().
  FakeGvCamera(const std::string& address, const std::string& serial);
  ~FakeGvCamera();
  FakeGvCamera(const FakeGvCamera&) = delete;
  FakeGvCamera& operator=(const FakeGvCamera&) = delete;
  // Serving, and answering discovery at its address with its own serial number.
  bool running() const;
  // Each GVSP packet (leader, payload, trailer) is left unsent with this probability (0..1): the
  // fake camera's own loss simulation, as a congested link loses packets. It answers no resend.
  void set_lost_packet_ratio(double ratio);

  // Frames to send, in order, one per frame the camera streams; after the last, the camera sends
  // them again from the first (with their timestamps advanced by `loop_period_ns` per lap).
  void serve(std::vector<ServedFrame> frames, std::uint64_t loop_period_ns = 0);
  // Frames served so far (the index into `serve`'s vector of each fill, including laps).
  std::size_t served_count() const;

  // Fills the buffer the camera is about to stream (on the fake camera's thread).
  void fill(ArvBuffer* buffer, std::uint32_t pixel_format);

 private:
  std::string address_, serial_;
  ArvGvFakeCamera* camera_ = nullptr;
  mutable std::mutex mutex_;
  std::vector<ServedFrame> frames_;
  std::uint64_t loop_period_ns_ = 0;
  std::size_t served_ = 0;
};

// arv-fake-gv-camera-0.8 -i ADDRESS -s SERIAL as a child process.
class FakeGvProcess {
 public:
  FakeGvProcess(std::string address, std::string serial)
      : address_(std::move(address)), serial_(std::move(serial)) {}
  ~FakeGvProcess() { kill(); }
  // Starts the program and waits until it answers GVCP discovery (false after `timeout_s`).
  bool start(double timeout_s = 5.0);
  void kill();  // SIGKILL and reap
  bool alive() const { return pid_ > 0; }

 private:
  std::string address_, serial_;
  pid_t pid_ = -1;
};

}  // namespace augrig::test
