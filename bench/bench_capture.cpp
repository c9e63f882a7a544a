// bench_capture: what one GigE Vision camera costs the receiving host, per frame, through
// AravisSource (capture/aravis_source.hpp): host CPU per frame and the latency from the device
// timestamp to the frame being available to read(), for 1280x960 BayerRG8 at 30 fps and at the
// fastest rate loopback allows. Prints the figures for docs/PERFORMANCE.md.
//   build/bench_capture [--seconds S] [--warmup S] [--rates 60,120,...] [--packet-socket 0|1]
//                       [--socket-buffer BYTES] [--compare-packet-socket] [--start-tries N]
//                       [--address IPV4]
// Cases: 30 fps with the negotiated packet size, with 1400-byte and with 8000-byte packets, then the
// frame rate stepped up (--rates) with 8000-byte packets and a few rates with 9000-byte packets;
// --compare-packet-socket adds rows through the other receive path (plain UDP sockets when the
// packet socket is in use), with Aravis' automatic socket buffer and with a 4 MiB one.
// The camera is Aravis' fake GigE Vision camera on 127.0.0.1 (--address), in a child process forked
// before anything else happens, so that the receiver's CPU (getrusage of this process: the reading
// thread and Aravis' stream thread) is measured alone. The camera's fill callback writes a fixed
// textured 1280x960 pattern with a frame counter in a few bytes, then stamps the frame with the
// child's CLOCK_MONOTONIC; the fake camera sends the GVSP packets right after the fill. t_host_ns is
// the parent's CLOCK_MONOTONIC when read() got the frame, so t_host_ns - t_ns is the time from the
// device timestamp to the frame being available: GVSP transfer, reassembly in Aravis' stream thread
// and the hand-over to the reading thread.
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <arv.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "capture/aravis_source.hpp"
#include "core/clock.hpp"

using namespace augrig;
namespace fs = std::filesystem;

namespace {

constexpr int kW = 1280, kH = 960;
// Where the camera serves (--address): an address of a local interface.
const char* g_address = "127.0.0.1";
// GigE Vision bootstrap register SCPS0 (stream channel 0 packet size; the size in its low 16 bits).
constexpr guint32 kScps0Register = 0x0d04;

// What the camera process tells the receiver, in a page both share (mapped before the fork).
struct Shared {
  std::atomic<std::uint64_t> frames_filled{0};
  std::atomic<std::uint32_t> packet_size{0};  // GVSP packet size the camera last sent with
};

// ---------------------------------------------------------------------------------------------
// The camera process.

struct CameraState {
  ArvFakeCamera* camera = nullptr;
  Shared* shared = nullptr;
  std::vector<std::uint8_t> pattern;
  std::size_t pattern_row = 0;
  int pattern_h = 0;
  std::uint64_t counter = 0;
};

// A fixed texture (gradients, hard edges, a little noise) standing in for a real image.
void make_pattern(CameraState& s, std::size_t row, int h) {
  s.pattern.resize(row * static_cast<std::size_t>(h));
  std::uint32_t lcg = 12345;
  for (int y = 0; y < h; ++y) {
    for (std::size_t x = 0; x < row; ++x) {
      lcg = lcg * 1664525u + 1013904223u;
      const double v = 110.0 + 50.0 * std::sin(static_cast<double>(x) / 17.0) * std::cos(y / 23.0) +
                       (((x / 64) + (y / 48)) % 2 ? 30.0 : 0.0) + static_cast<double>(lcg >> 29);
      s.pattern[static_cast<std::size_t>(y) * row + x] = static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
    }
  }
  s.pattern_row = row;
  s.pattern_h = h;
}

// On the fake camera's thread, just before it sends the frame. Aravis 0.8.26 hands the buffer with
// its size reading 0, so the image size comes from the region and the pixel format.
void fill(ArvBuffer* buffer, void* data, guint32, guint32, ArvPixelFormat pixel_format) {
  auto& s = *static_cast<CameraState*>(data);
  std::size_t ignored = 0;
  auto* out = static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, &ignored)));
  const int w = arv_buffer_get_image_width(buffer), h = arv_buffer_get_image_height(buffer);
  const std::size_t row = static_cast<std::size_t>(w) * ARV_PIXEL_FORMAT_BIT_PER_PIXEL(pixel_format) / 8;
  if (row != s.pattern_row || h != s.pattern_h) make_pattern(s, row, h);
  std::memcpy(out, s.pattern.data(), s.pattern.size());
  // A few bytes change per frame: the counter at the start of four rows.
  ++s.counter;
  for (int k = 0; k < 4 && row >= sizeof s.counter; ++k)
    std::memcpy(out + static_cast<std::size_t>(h * k / 4) * row, &s.counter, sizeof s.counter);
  guint32 scps = 0;
  arv_fake_camera_read_register(s.camera, kScps0Register, &scps);
  s.shared->packet_size.store(scps & 0xffff);
  s.shared->frames_filled.fetch_add(1);
  // Last: the fake camera sends the leader (with this timestamp) and the data right after.
  arv_buffer_set_timestamp(buffer, static_cast<guint64>(monotonic_now_ns()));
}

// Starts the camera, tells the parent "OK" or "FAIL ..." on `status_fd`, then serves until the
// parent closes `command_fd` (or dies).
[[noreturn]] void camera_process(int status_fd, int command_fd, Shared* shared, const std::string& serial) {
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  CameraState state;
  state.shared = shared;
  ArvGvFakeCamera* gv = arv_gv_fake_camera_new(g_address, serial.c_str());
  const bool ok = gv && arv_gv_fake_camera_is_running(gv);
  if (ok) {
    state.camera = arv_gv_fake_camera_get_fake_camera(gv);
    arv_fake_camera_set_fill_pattern(state.camera, &fill, &state);
  }
  const std::string msg = ok ? "OK\n" : "FAIL arv_gv_fake_camera_new() did not start\n";
  if (write(status_fd, msg.data(), msg.size()) < 0) _exit(3);
  close(status_fd);
  if (!ok) _exit(2);
  char c = 0;
  while (read(command_fd, &c, 1) > 0) {
  }
  _exit(0);  // the parent reaps us; no teardown needed
}

// ---------------------------------------------------------------------------------------------
// The receiver.

// Who answers GigE Vision discovery at ADDRESS:3956 within `timeout_ms`: the serial number from the
// discovery ack ("" when nothing answers). Plain sockets: no GLib in the parent before the fork.
std::string discover_serial(const char* address, int timeout_ms) {
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return "";
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(3956);
  inet_pton(AF_INET, address, &to.sin_addr);
  // GVCP header: key 0x42, flags (ack wanted), DISCOVERY_CMD 0x0002, length 0, request id.
  const std::uint8_t cmd[8] = {0x42, 0x01, 0x00, 0x02, 0x00, 0x00, 0x5e, 0x11};
  std::string serial;
  if (sendto(fd, cmd, sizeof cmd, 0, reinterpret_cast<const sockaddr*>(&to), sizeof to) == sizeof cmd) {
    pollfd p{fd, POLLIN, 0};
    const std::int64_t until = monotonic_now_ns() + timeout_ms * 1'000'000LL;
    while (serial.empty() && monotonic_now_ns() < until &&
           poll(&p, 1, static_cast<int>((until - monotonic_now_ns()) / 1'000'000) + 1) == 1) {
      std::uint8_t ack[600];
      const ssize_t n = recv(fd, ack, sizeof ack, 0);
      // Ack: status 0, DISCOVERY_ACK 0x0003, length, our id; the bootstrap registers follow, the
      // serial number at 0xD8 (16 bytes).
      if (n >= 8 + 0xE8 && ack[2] == 0x00 && ack[3] == 0x03 && ack[6] == 0x5e && ack[7] == 0x11)
        serial.assign(reinterpret_cast<const char*>(ack + 8 + 0xD8),
                      strnlen(reinterpret_cast<const char*>(ack + 8 + 0xD8), 16));
    }
  }
  close(fd);
  return serial;
}

// The camera process, killed and reaped whichever way main() ends.
struct Child {
  pid_t pid = -1;
  int command_fd = -1;
  ~Child() { stop(); }
  void stop() {
    if (command_fd >= 0) close(command_fd);
    command_fd = -1;
    if (pid <= 0) return;
    kill(pid, SIGKILL);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    pid = -1;
  }
  // Forks the camera process and waits until the address answers discovery with its serial. Aravis
  // 0.8.26 reports the camera running even when another process holds 127.0.0.1:3956 (a test's
  // fake camera), so only the serial tells whose camera answers. Returns "" or why it failed.
  std::string start(Shared* shared, const std::string& serial) {
    int status_pipe[2], command_pipe[2];
    if (pipe(status_pipe) != 0) return std::string("pipe: ") + std::strerror(errno);
    if (pipe(command_pipe) != 0) {
      close(status_pipe[0]);
      close(status_pipe[1]);
      return std::string("pipe: ") + std::strerror(errno);
    }
    shared->frames_filled = 0;
    shared->packet_size = 0;
    pid = fork();
    if (pid < 0) return std::string("fork: ") + std::strerror(errno);
    if (pid == 0) {
      close(status_pipe[0]);
      close(command_pipe[1]);
      camera_process(status_pipe[1], command_pipe[0], shared, serial);
    }
    close(status_pipe[1]);
    close(command_pipe[0]);
    command_fd = command_pipe[1];
    std::string status;
    pollfd p{status_pipe[0], POLLIN, 0};
    const std::int64_t give_up = monotonic_now_ns() + 10'000'000'000LL;
    while (status.find('\n') == std::string::npos && monotonic_now_ns() < give_up) {
      if (poll(&p, 1, 200) <= 0) continue;
      char b[256];
      const ssize_t n = read(status_pipe[0], b, sizeof b);
      if (n <= 0) break;
      status.append(b, static_cast<std::size_t>(n));
    }
    close(status_pipe[0]);
    if (status.rfind("OK", 0) != 0)
      return status.empty() ? "the camera process said nothing within 10 s"
                            : status.substr(0, status.size() - 1);
    std::string who;
    for (int i = 0; i < 10 && who != serial; ++i) who = discover_serial(g_address, 100);
    if (who == serial) return "";
    return who.empty() ? std::string("nothing answers discovery at ") + g_address + ":3956"
                       : std::string(g_address) +
                             ":3956 is held by another process (its camera answers as '" + who + "')";
  }
};

// CPU time of this process (all threads, user + system), ns.
std::int64_t process_cpu_ns() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  auto ns = [](const timeval& t) {
    return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_usec * 1000;
  };
  return ns(u.ru_utime) + ns(u.ru_stime);
}

// CPU time of another process, summed over its threads (the scheduler's own ns figure).
std::int64_t other_process_cpu_ns(pid_t pid) {
  std::int64_t total = 0;
  std::error_code ec;
  for (const auto& task : fs::directory_iterator("/proc/" + std::to_string(pid) + "/task", ec)) {
    std::ifstream in(task.path() / "schedstat");
    std::int64_t run_ns = 0;
    if (in >> run_ns) total += run_ns;
  }
  return total;
}

// Whether this process holds an AF_PACKET socket (Aravis' packet-socket receive path).
bool holds_packet_socket() {
  std::set<std::string> inodes;
  std::ifstream in("/proc/net/packet");
  std::string line;
  std::getline(in, line);  // header; the inode is the last column
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string f, last;
    while (fields >> f) last = f;
    if (!last.empty()) inodes.insert(last);
  }
  std::error_code ec;
  for (const auto& fd : fs::directory_iterator("/proc/self/fd", ec)) {
    const std::string target = fs::read_symlink(fd.path(), ec).string();
    if (target.rfind("socket:[", 0) == 0 && inodes.count(target.substr(8, target.size() - 9))) return true;
  }
  return false;
}

std::string first_line(const std::string& path, const std::string& key = "") {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line))
    if (key.empty() || line.rfind(key, 0) == 0) return key.empty() ? line : line.substr(line.find(':') + 2);
  return "?";
}

std::string load_average() {
  double l[3] = {0, 0, 0};
  if (getloadavg(l, 3) != 3) return "?";
  char b[64];
  std::snprintf(b, sizeof b, "%.2f %.2f %.2f", l[0], l[1], l[2]);
  return b;
}

struct Case {
  std::string name;
  double rate_hz;
  int packet_size;  // 0: negotiated
  bool packet_socket;
  int socket_buffer = 0;  // 0: Aravis sizes it (to one frame)
};

struct Result {
  bool ok = false;
  std::string error;
  double camera_rate_hz = 0;  // as the camera reports it after the request
  int packet_size = 0;        // as the camera sent
  double fps = 0;             // frames read per second of the window
  double sent_fps = 0;        // frames the camera filled and sent per second
  double cpu_ms = 0;          // receiver CPU per frame read
  double camera_cpu_ms = 0;   // camera process CPU per frame sent
  double lat_p50_ms = 0, lat_p99_ms = 0, lat_max_ms = 0;
  std::uint64_t frames = 0, camera_drops = 0, transport_drops = 0, underruns = 0, missing = 0, resend_req = 0,
                resent = 0;
  bool packet_socket_used = false;
  bool drops() const { return camera_drops || transport_drops || underruns || missing; }
};

// Reads until nothing is queued (read() refreshes Aravis' stream counters when it times out).
bool drain(AravisSource& src, Result& r) {
  Frame f;
  for (int i = 0; i < 10000; ++i) {
    auto s = src.read(f, std::chrono::nanoseconds(0));
    if (!s) {
      r.error = s.error().message;
      return false;
    }
    if (*s == ReadStatus::kTimeout) return true;
  }
  r.error = "frames kept coming while draining";
  return false;
}

double percentile_ms(std::vector<std::int64_t>& v, double p) {
  if (v.empty()) return 0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(std::ceil(p * v.size())) - 1);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k] * 1e-6;
}

Result run_case(const Case& c, double seconds, double warmup_s, const std::string& serial, pid_t camera_pid,
                Shared* shared) {
  Result r;
  AravisOptions o;
  o.device = g_address;
  o.pixel_format = "BayerRG8";
  o.roi = RegionOfInterest{0, 0, kW, kH};
  o.frame_rate_hz = c.rate_hz;
  o.packet_size = c.packet_size;
  o.packet_socket = c.packet_socket;
  o.socket_buffer_bytes = c.socket_buffer;
  o.timestamp_at_exposure_start = false;  // t_ns is the raw device timestamp
  o.reconnect = false;
  auto opened = AravisSource::open(o);
  if (!opened) {
    r.error = opened.error().message;
    return r;
  }
  AravisSource& src = **opened;
  const AravisCameraInfo info = src.info();
  if (info.serial != serial) {
    r.error = std::string(g_address) + " answers as serial '" + info.serial + "', not this bench's camera " +
              serial;
    return r;
  }
  r.camera_rate_hz = info.frame_rate_hz;

  Frame f;
  const std::int64_t warm_end = monotonic_now_ns() + static_cast<std::int64_t>(warmup_s * 1e9);
  while (monotonic_now_ns() < warm_end) {
    auto s = src.read(f, std::chrono::milliseconds(100));
    if (!s) {
      r.error = s.error().message;
      return r;
    }
  }
  if (!drain(src, r)) return r;
  const AravisStats s0 = src.stats();
  const std::uint64_t sent0 = shared->frames_filled.load();
  const std::int64_t cpu0 = process_cpu_ns(), cam0 = other_process_cpu_ns(camera_pid),
                     t0 = monotonic_now_ns();
  const std::int64_t t_end = t0 + static_cast<std::int64_t>(seconds * 1e9);
  std::vector<std::int64_t> latency_ns;
  latency_ns.reserve(static_cast<std::size_t>(seconds * 1100) + 16);
  while (monotonic_now_ns() < t_end) {
    auto s = src.read(f, std::chrono::milliseconds(100));
    if (!s) {
      r.error = s.error().message;
      return r;
    }
    if (*s == ReadStatus::kFrame) latency_ns.push_back(f.t_host_ns - f.t_ns);
  }
  const std::int64_t t1 = monotonic_now_ns(), cpu1 = process_cpu_ns(),
                     cam1 = other_process_cpu_ns(camera_pid);
  const std::uint64_t sent1 = shared->frames_filled.load();
  r.packet_socket_used = holds_packet_socket();
  if (!drain(src, r)) return r;
  const AravisStats s1 = src.stats();
  if (!src.health().connected) {
    r.error = "camera lost: " + src.health().message;
    return r;
  }

  const double wall_s = static_cast<double>(t1 - t0) * 1e-9;
  r.frames = latency_ns.size();
  r.fps = static_cast<double>(r.frames) / wall_s;
  r.sent_fps = static_cast<double>(sent1 - sent0) / wall_s;
  r.cpu_ms = r.frames ? static_cast<double>(cpu1 - cpu0) * 1e-6 / static_cast<double>(r.frames) : 0;
  r.camera_cpu_ms =
      sent1 > sent0 ? static_cast<double>(cam1 - cam0) * 1e-6 / static_cast<double>(sent1 - sent0) : 0;
  r.packet_size = static_cast<int>(shared->packet_size.load());
  r.camera_drops = s1.camera_drops - s0.camera_drops;
  r.transport_drops = s1.transport_drops - s0.transport_drops;
  r.underruns = s1.underruns - s0.underruns;
  r.missing = s1.missing_packets - s0.missing_packets;
  r.resend_req = s1.resend_requests - s0.resend_requests;
  r.resent = s1.resent_packets - s0.resent_packets;
  r.lat_max_ms = latency_ns.empty() ? 0 : *std::max_element(latency_ns.begin(), latency_ns.end()) * 1e-6;
  r.lat_p50_ms = percentile_ms(latency_ns, 0.50);
  r.lat_p99_ms = percentile_ms(latency_ns, 0.99);
  r.ok = r.frames > 0;
  if (!r.ok) r.error = "no frame in " + std::to_string(seconds) + " s";
  return r;
}

std::string receive_path(const Case& c, const Result& r) {
  if (r.packet_socket_used) return "packet socket";
  if (c.socket_buffer == 0) return "UDP, auto buffer";
  char b[64];
  std::snprintf(b, sizeof b, "UDP, %.1f MiB buffer", c.socket_buffer / 1048576.0);
  return b;
}

void print_header() {
  std::printf(
      "| case | receive path | asked fps | camera fps | packet B | sent fps | read fps | CPU ms / frame | "
      "latency p50 / p99 / max ms | camera drops | transport drops | underruns | missing pkts | resends "
      "(asked / got) | camera CPU ms / frame |\n");
  std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
}

void print_row(const Case& c, const Result& r) {
  if (!r.ok) {
    std::printf("| %s | | %.0f | failed: %s |\n", c.name.c_str(), c.rate_hz, r.error.c_str());
    std::fflush(stdout);
    return;
  }
  auto u = [](std::uint64_t v) { return static_cast<unsigned long long>(v); };
  std::printf(
      "| %s | %s | %.0f | %.2f | %d | %.1f | %.1f | %.3f | %.2f / %.2f / %.2f | %llu | %llu | %llu | %llu | "
      "%llu / %llu | %.3f |\n",
      c.name.c_str(), receive_path(c, r).c_str(), c.rate_hz, r.camera_rate_hz, r.packet_size, r.sent_fps,
      r.fps, r.cpu_ms, r.lat_p50_ms, r.lat_p99_ms, r.lat_max_ms, u(r.camera_drops), u(r.transport_drops),
      u(r.underruns), u(r.missing), u(r.resend_req), u(r.resent), r.camera_cpu_ms);
  std::fflush(stdout);
}

std::vector<double> parse_rates(const std::string& s) {
  std::vector<double> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ','))
    if (const double v = std::atof(item.c_str()); v > 0) out.push_back(v);
  return out;
}

int usage() {
  std::fprintf(stderr,
               "usage: bench_capture [--seconds S] [--warmup S] [--rates 60,120,...] [--packet-socket 0|1] "
               "[--socket-buffer BYTES] [--compare-packet-socket] [--start-tries N] [--address IPV4]\n");
  return 2;
}

// The command line; defaults as documented at the top of the file.
struct Options {
  double seconds = 5, warmup_s = 0.5;
  std::vector<double> rates = {60, 120, 240, 300, 400, 500, 600, 800, 1000};
  bool packet_socket = true, compare_packet_socket = false;
  int socket_buffer = 0, start_tries = 20;
};

// Empty when an argument is not understood (the caller prints the usage).
std::optional<Options> parse_options(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--seconds" && has_value)
      o.seconds = std::max(0.5, std::atof(argv[++i]));
    else if (a == "--warmup" && has_value)
      o.warmup_s = std::max(0.0, std::atof(argv[++i]));
    else if (a == "--rates" && has_value)
      o.rates = parse_rates(argv[++i]);
    else if (a == "--packet-socket" && has_value)
      o.packet_socket = std::atoi(argv[++i]) != 0;
    else if (a == "--socket-buffer" && has_value)
      o.socket_buffer = std::max(0, std::atoi(argv[++i]));
    else if (a == "--start-tries" && has_value)
      o.start_tries = std::max(1, std::atoi(argv[++i]));
    else if (a == "--address" && has_value)
      g_address = argv[++i];
    else if (a == "--compare-packet-socket")
      o.compare_packet_socket = true;
    else
      return std::nullopt;
  }
  return o;
}

// Starts the camera process, up to start_tries times 0.5 s apart (a start can fail transiently).
bool start_camera(Child& child, Shared* shared, const std::string& serial, int start_tries) {
  std::string why;
  for (int attempt = 1; attempt <= start_tries; ++attempt) {
    why = child.start(shared, serial);
    if (why.empty()) break;
    child.stop();
    std::fprintf(stderr, "bench_capture: camera start %d of %d failed: %s\n", attempt, start_tries,
                 why.c_str());
    if (attempt < start_tries) std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  if (!why.empty()) {
    std::fprintf(stderr, "bench_capture: could not start the fake camera after %d tries 0.5 s apart: %s\n",
                 start_tries, why.c_str());
    return false;
  }
  return true;
}

// What the camera accepts: AcquisitionFrameRate's bounds. False when the camera cannot be reached.
bool frame_rate_bounds(double& rate_min, double& rate_max) {
  GError* e = nullptr;
  ArvCamera* cam = arv_camera_new(g_address, &e);
  if (!cam) {
    std::fprintf(stderr, "bench_capture: %s: %s\n", g_address, e ? e->message : "cannot connect");
    g_clear_error(&e);
    return false;
  }
  arv_camera_get_frame_rate_bounds(cam, &rate_min, &rate_max, &e);
  g_clear_error(&e);
  g_object_unref(cam);
  return true;
}

void print_setup(const Options& o, const std::string& serial, pid_t camera_pid, double rate_min,
                 double rate_max) {
  utsname u{};
  uname(&u);
  std::printf("bench_capture: %s, %u hardware threads, Linux %s, Aravis %u.%u.%u\n",
              first_line("/proc/cpuinfo", "model name").c_str(), std::thread::hardware_concurrency(),
              u.release, arv_get_major_version(), arv_get_minor_version(), arv_get_micro_version());
  std::printf(
      "camera: Aravis fake GigE Vision camera (serial %s) in child process %d on %s, %dx%d BayerRG8; "
      "AcquisitionFrameRate accepts %.1f to %.1f fps (an integer frame period in us)\n",
      serial.c_str(), static_cast<int>(camera_pid), g_address, kW, kH, rate_min, rate_max);
  std::printf("loopback MTU %s, net.core.rmem_max %s; %.1f s per case after %.1f s warm-up\n",
              first_line("/sys/class/net/lo/mtu").c_str(), first_line("/proc/sys/net/core/rmem_max").c_str(),
              o.seconds, o.warmup_s);
  std::printf("load average before: %s\n\n", load_average().c_str());
}

// The cases in the order they run; those faster than the camera allows are dropped (with a line).
std::vector<Case> make_cases(const Options& o, double rate_max) {
  auto name = [](double rate, int size) {
    return std::to_string(static_cast<int>(rate)) + " fps, " +
           (size ? std::to_string(size) + "-byte packets" : std::string("negotiated packet size"));
  };
  const bool ps = o.packet_socket;
  const int sb = o.socket_buffer;
  // The fake camera cannot fire GVCP test packets (no GevSCPSFireTestPacket), so "negotiated" keeps
  // the size it has: 1400 bytes at start-up, hence that case runs first.
  std::vector<Case> cases;
  for (int size : {0, 1400, 8000}) cases.push_back({name(30, size), 30, size, ps, sb});
  std::vector<double> rates_9000 = {240, 400, 600, 1000};
  for (double r : o.rates) cases.push_back({name(r, 8000), r, 8000, ps, sb});
  cases.push_back({name(30, 9000), 30, 9000, ps, sb});
  for (double r : rates_9000) cases.push_back({name(r, 9000), r, 9000, ps, sb});
  if (o.compare_packet_socket) {
    // The other receive path; plain UDP sockets with Aravis' own buffer size and with 4 MiB.
    const std::vector<int> buffers = ps ? std::vector<int>{0, 4 << 20} : std::vector<int>{0};
    for (int buffer : buffers)
      for (const auto& [r, size] :
           {std::pair{30.0, 1400}, std::pair{30.0, 8000}, std::pair{240.0, 8000}, std::pair{400.0, 9000}})
        cases.push_back({name(r, size), r, size, !ps, buffer});
  }
  std::erase_if(cases, [&](const Case& c) {
    if (rate_max <= 0 || c.rate_hz <= rate_max) return false;
    std::printf("(%s skipped: the camera's maximum is %.1f fps)\n", c.name.c_str(), rate_max);
    return true;
  });
  return cases;
}

// Per receive path: the fastest case read with nothing lost, and the lowest rate that lost anything.
struct Summary {
  double best_fps = 0;
  std::string best_case;
  std::optional<std::string> first_loss;
  double first_loss_rate = 0;
};
using Summaries = std::vector<std::pair<std::string, Summary>>;

void add_to_summary(Summaries& summaries, const Case& c, const Result& r) {
  const std::string path = receive_path(c, r);
  auto it = std::find_if(summaries.begin(), summaries.end(), [&](const auto& p) { return p.first == path; });
  if (it == summaries.end()) it = summaries.insert(summaries.end(), {path, Summary{}});
  Summary& s = it->second;
  if (r.drops() && (!s.first_loss || c.rate_hz < s.first_loss_rate)) {
    s.first_loss = c.name;
    s.first_loss_rate = c.rate_hz;
  }
  if (!r.drops() && r.fps > s.best_fps) {
    s.best_fps = r.fps;
    s.best_case = c.name;
  }
}

// Runs every case, a table row each, then the per-path summary lines.
void run_cases(const std::vector<Case>& cases, const Options& o, const std::string& serial, pid_t camera_pid,
               Shared* shared) {
  print_header();
  Summaries summaries;
  for (const Case& c : cases) {
    const Result r = run_case(c, o.seconds, o.warmup_s, serial, camera_pid, shared);
    print_row(c, r);
    if (r.ok) add_to_summary(summaries, c, r);
  }
  std::printf("\nload average after: %s\n", load_average().c_str());
  for (const auto& [path, s] : summaries)
    std::printf("%s: fastest with nothing lost %.1f fps read (%s); %s\n", path.c_str(), s.best_fps,
                s.best_case.c_str(),
                s.first_loss ? ("first loss at " + *s.first_loss).c_str() : "no case lost anything");
}

// What the columns mean.
void print_legend(double seconds) {
  std::printf(
      "\nreceive path: an AF_PACKET socket held by this process while streaming (Aravis' packet socket, "
      "which "
      "needs CAP_NET_RAW), or plain UDP sockets. asked fps: frame rate requested; camera fps: "
      "AcquisitionFrameRate read back; packet B: the GVSP packet size the camera sent with; sent fps: frames "
      "the camera filled and sent; read fps: frames read() returned, per second of the %.1f s window. CPU ms "
      "/ "
      "frame: user + system time of this (receiving) process over the window (the reading thread, which "
      "copies each frame out, and Aravis' stream thread) per frame read. latency: t_host_ns (CLOCK_MONOTONIC "
      "when read() got the frame) minus the device timestamp (the camera process's CLOCK_MONOTONIC at the "
      "end "
      "of its fill, just before the first GVSP packet is sent). camera CPU: the fake camera process per "
      "frame "
      "sent, not the receiver's; on loopback the kernel's receive work (the copy into the receiver's socket "
      "or packet ring) runs in the sender's context and is counted here, and so is the camera's busy-wait "
      "before each frame.\n",
      seconds);
}

}  // namespace

int main(int argc, char** argv) {
  const std::optional<Options> options = parse_options(argc, argv);
  if (!options) return usage();
  const Options& o = *options;

  // Fork first, before GLib or Aravis start any thread in this process.
  auto* shared = static_cast<Shared*>(
      mmap(nullptr, sizeof(Shared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0));
  if (shared == MAP_FAILED) {
    std::perror("bench_capture: mmap");
    return 1;
  }
  new (shared) Shared();
  const std::string serial = "BENCH" + std::to_string(getpid());
  Child child;
  if (!start_camera(child, shared, serial, o.start_tries)) return 1;

  double rate_min = 0, rate_max = 0;
  if (!frame_rate_bounds(rate_min, rate_max)) return 1;
  print_setup(o, serial, child.pid, rate_min, rate_max);
  const std::vector<Case> cases = make_cases(o, rate_max);
  run_cases(cases, o, serial, child.pid, shared);
  print_legend(o.seconds);
  child.stop();
  return 0;
}
