#include "tests/support/fake_gv_camera.hpp"

#include <chrono>
#include <cstring>
#include <thread>

#include <arv.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tests/support/test_support.hpp"

namespace augrig::test {
namespace {
void fill_trampoline(ArvBuffer* buffer, void* self, guint32, guint32, ArvPixelFormat pixel_format) {
  static_cast<FakeGvCamera*>(self)->fill(buffer, pixel_format);
}
}  // namespace

bool ensure_loopback_address(const std::string& address, std::string* why) {
  std::string out;
  run_command("ip -4 addr show dev lo", &out);
  if (out.find(" " + address + "/") != std::string::npos) return true;
  if (run_command("ip addr add " + address + "/8 dev lo", &out) == 0) return true;
  if (why) *why = "loopback lacks " + address + " and `ip addr add " + address + "/8 dev lo` failed: " + out;
  return false;
}

FakeGvCamera::FakeGvCamera(const std::string& address, const std::string& serial)
    : address_(address), serial_(serial) {
  camera_ = arv_gv_fake_camera_new(address.c_str(), serial.c_str());
  if (camera_)
    arv_fake_camera_set_fill_pattern(arv_gv_fake_camera_get_fake_camera(camera_), &fill_trampoline, this);
}

void FakeGvCamera::set_lost_packet_ratio(double ratio) {
  if (camera_) g_object_set(camera_, "gvsp-lost-ratio", ratio, nullptr);
}

FakeGvCamera::~FakeGvCamera() {
  if (camera_) g_object_unref(camera_);
}

bool FakeGvCamera::running() const {
  if (!camera_ || !arv_gv_fake_camera_is_running(camera_)) return false;
  // Aravis says "running" even when another process already holds the address's GVCP port; then
  // discovery answers with that camera's serial. Wait (a while: another run may end) for ours.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (std::chrono::steady_clock::now() < until) {
    arv_update_device_list();
    for (unsigned i = 0; i < arv_get_n_devices(); ++i) {
      const char* serial = arv_get_device_serial_nbr(i);
      const char* address = arv_get_device_address(i);
      if (serial && address && serial_ == serial && address_ == address) return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  return false;
}

void FakeGvCamera::serve(std::vector<ServedFrame> frames, std::uint64_t loop_period_ns) {
  std::lock_guard lock(mutex_);
  frames_ = std::move(frames);
  loop_period_ns_ = loop_period_ns;
  served_ = 0;
}

std::size_t FakeGvCamera::served_count() const {
  std::lock_guard lock(mutex_);
  return served_;
}

// Called on the fake camera's thread for each frame it streams. Aravis 0.8 hands the buffer with
// its size not yet set, so the image size comes from the region and the pixel format.
void FakeGvCamera::fill(ArvBuffer* buffer, std::uint32_t pixel_format) {
  FakeGvCamera* self = this;
  size_t ignored = 0;
  auto* data = static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, &ignored)));
  const int w = arv_buffer_get_image_width(buffer), h = arv_buffer_get_image_height(buffer);
  const std::size_t row = static_cast<std::size_t>(w) * ARV_PIXEL_FORMAT_BIT_PER_PIXEL(pixel_format) / 8;
  std::lock_guard lock(self->mutex_);
  if (self->frames_.empty()) {
    std::memset(data, 0, row * h);
    return;
  }
  const std::size_t n = self->frames_.size();
  const ServedFrame& f = self->frames_[self->served_ % n];
  const std::uint64_t lap = self->served_ / n;
  for (int y = 0; y < h; ++y) {
    if (y < f.image.height() && row <= f.image.stride_bytes())
      std::memcpy(data + y * row, f.image.row(y), row);
    else
      std::memset(data + y * row, 0, row);
  }
  arv_buffer_set_timestamp(buffer, f.timestamp_ns + lap * self->loop_period_ns_);
  self->served_++;
}

bool FakeGvProcess::start(double timeout_s) {
  kill();
  pid_ = fork();
  if (pid_ == 0) {
    execlp("arv-fake-gv-camera-0.8", "arv-fake-gv-camera-0.8", "-i", address_.c_str(), "-s", serial_.c_str(),
           static_cast<char*>(nullptr));
    _exit(127);
  }
  if (pid_ < 0) return false;
  // Ready when discovery sees it.
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < until) {
    arv_update_device_list();
    for (unsigned i = 0; i < arv_get_n_devices(); ++i) {
      const char* serial = arv_get_device_serial_nbr(i);
      if (serial && serial_ == serial) return true;
    }
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

void FakeGvProcess::kill() {
  if (pid_ <= 0) return;
  ::kill(pid_, SIGKILL);
  int status = 0;
  waitpid(pid_, &status, 0);
  pid_ = -1;
}

}  // namespace augrig::test
