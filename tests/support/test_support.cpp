#include "tests/support/test_support.hpp"

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

namespace augrig::test {

std::string data_path(const std::string& relative) {
  return std::string(AUGRIG_TEST_DATA_DIR) + "/" + relative;
}

namespace {

// Removes the directories output_dir() made in this process once the program has passed. CTest
// runs one test per process, so this is the outputs of one passed test; a run of all tests leaves
// only what failed (several GB otherwise).
class OutputCleanup : public ::testing::EmptyTestEventListener {
 public:
  void add(const std::filesystem::path& dir) {
    std::lock_guard lock(mutex_);
    dirs_.push_back(dir);
  }
  void OnTestProgramEnd(const ::testing::UnitTest& unit_test) override {
    const char* keep = std::getenv("AUGRIG_KEEP_TEST_OUTPUT");
    if (!unit_test.Passed() || (keep && std::string(keep) != "0")) return;
    std::lock_guard lock(mutex_);
    for (const std::filesystem::path& d : dirs_) {
      std::error_code ec;  // best effort: a directory a child process still writes may stay
      std::filesystem::remove_all(d, ec);
    }
  }

 private:
  std::mutex mutex_;
  std::vector<std::filesystem::path> dirs_;
};

OutputCleanup& output_cleanup() {
  // Owned by GoogleTest's listener list once appended.
  static OutputCleanup* cleanup = [] {
    auto* c = new OutputCleanup;
    ::testing::UnitTest::GetInstance()->listeners().Append(c);
    return c;
  }();
  return *cleanup;
}

}  // namespace

std::string output_dir(const std::string& name) {
  const std::filesystem::path p = std::filesystem::path(AUGRIG_TEST_OUTPUT_DIR) / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  output_cleanup().add(p);
  return p.string();
}

std::string augrig_binary() {
  return AUGRIG_BINARY;
}

int run_command(const std::string& command, std::string* output) {
  const std::string full = command + " 2>&1";
  FILE* pipe = popen(full.c_str(), "r");
  if (!pipe) return -1;
  std::array<char, 4096> buf{};
  std::string out;
  while (std::fgets(buf.data(), buf.size(), pipe)) out += buf.data();
  const int status = pclose(pipe);
  if (output) *output = out;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

int run_augrig(const std::string& args, std::string* output) {
  return run_command(augrig_binary() + " " + args + " 2>&1", output);
}

std::string npm_script(const std::string& name, const std::vector<std::string>& packages,
                       const std::string& script, std::string* why) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(AUGRIG_TEST_OUTPUT_DIR) / ("npm-" + name);
  fs::create_directories(dir);
  std::string log;
  if (run_command("node --version", &log) != 0) {
    *why = "node is not installed: " + log;
    return "";
  }
  // One process at a time installs; the others wait here and then find it done.
  const int lock = ::open((dir / ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock < 0 || ::flock(lock, LOCK_EX) != 0) {
    *why = "cannot lock " + (dir / ".lock").string();
    if (lock >= 0) ::close(lock);
    return "";
  }
  std::string list;
  for (const std::string& p : packages) list += (list.empty() ? "" : " ") + p;
  const fs::path marker = dir / ".installed";
  std::string done;
  if (std::FILE* f = std::fopen(marker.c_str(), "r")) {
    char buf[1024];
    const std::size_t n = std::fread(buf, 1, sizeof buf, f);
    done.assign(buf, n);
    std::fclose(f);
  }
  std::string result;
  if (done != list) {
    fs::remove(marker);
    if (run_command("cd " + dir.string() +
                        " && timeout 300 npm install --no-audit --no-fund --loglevel=error " + list + " 2>&1",
                    &log) != 0) {
      *why = "npm install of " + list + " failed: " + log;
      ::close(lock);
      return "";
    }
    if (std::FILE* f = std::fopen(marker.c_str(), "w")) {
      std::fputs(list.c_str(), f);
      std::fclose(f);
    }
  }
  // The script replaced whole (a rename), never rewritten under a node process reading it.
  const fs::path target = dir / script, tmp = dir / (script + ".tmp" + std::to_string(::getpid()));
  fs::copy_file(data_path("../support/" + script), tmp, fs::copy_options::overwrite_existing);
  fs::rename(tmp, target);
  ::close(lock);
  return target.string();
}

std::string sim_recording(const std::string& scenario, int every, const std::string& name, std::string* why) {
  namespace fs = std::filesystem;
  const fs::path root = fs::path(AUGRIG_TEST_OUTPUT_DIR) / "recordings";
  fs::create_directories(root);
  const int lock = ::open((root / (name + ".lock")).c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock < 0 || ::flock(lock, LOCK_EX) != 0) {
    *why = "cannot lock " + (root / (name + ".lock")).string();
    if (lock >= 0) ::close(lock);
    return "";
  }
  // Made again when augrig or the scenario changed since.
  auto stamp = [](const fs::path& p) {
    std::error_code ec;
    return std::to_string(fs::last_write_time(p, ec).time_since_epoch().count());
  };
  const fs::path dir = root / name, marker = root / (name + ".made");
  const std::string want = scenario + " " + std::to_string(every) + " " + stamp(augrig_binary()) + " " +
                           stamp(data_path(scenario));
  std::string have;
  if (std::FILE* f = std::fopen(marker.c_str(), "r")) {
    char buf[1024];
    have.assign(buf, std::fread(buf, 1, sizeof buf, f));
    std::fclose(f);
  }
  if (have != want || !fs::exists(dir / "recording.sqlite")) {
    fs::remove(marker);
    std::string log;
    if (run_augrig("run --source 'sim://" + data_path(scenario) + "?every=" + std::to_string(every) +
                       "&rate=0' --headless --status-every 0 --overwrite --record " + dir.string(),
                   &log) != 0) {
      *why = "augrig run --record failed: " + log;
      ::close(lock);
      return "";
    }
    if (std::FILE* f = std::fopen(marker.c_str(), "w")) {
      std::fputs(want.c_str(), f);
      std::fclose(f);
    }
  }
  ::close(lock);
  return dir.string();
}

void expect_same_fix(const nav::GpsFix& got, const nav::GpsFix& want, const std::string& what) {
  EXPECT_EQ(got.t_ns, want.t_ns) << what;
  EXPECT_EQ(got.antenna.lat_rad, want.antenna.lat_rad) << what;
  EXPECT_EQ(got.antenna.lon_rad, want.antenna.lon_rad) << what;
  EXPECT_EQ(got.antenna.h_m, want.antenna.h_m) << what;
  EXPECT_EQ(got.quality, want.quality) << what;
  EXPECT_EQ(got.satellites, want.satellites) << what;
  EXPECT_EQ(got.hdop, want.hdop) << what;
  EXPECT_EQ(got.geoid_separation_m, want.geoid_separation_m) << what;
  EXPECT_EQ(got.sigma_ned_m, want.sigma_ned_m) << what;
  EXPECT_EQ(got.ground_speed_mps, want.ground_speed_mps) << what;
  EXPECT_EQ(got.course_rad, want.course_rad) << what;
  EXPECT_EQ(got.heading_rad, want.heading_rad) << what;
}

Frame gradient_frame(const CameraModel& cm, PixelFormat fmt, CameraId id) {
  Frame f;
  f.image = Image(cm.width_px, cm.height_px, fmt);
  const int bpp = bytes_per_pixel(fmt);
  for (int y = 0; y < cm.height_px; ++y)
    for (int x = 0; x < cm.width_px; ++x)
      for (int c = 0; c < bpp; ++c)
        f.image.row(y)[x * bpp + c] = static_cast<std::uint8_t>((x * 7 + y * 3 + c * 50 + (x ^ y)) & 255);
  f.camera = id;
  return f;
}

Expected<WholeAndBoxAugmenters> whole_and_box_augmenters(const Rig& rig, AugmentOptions options) {
  WholeAndBoxAugmenters a;
  options.augmented_output = AugmentedOutput::kWholeImage;
  auto whole = Augmenter::create(rig, options);
  if (!whole) return whole.error();
  options.augmented_output = AugmentedOutput::kChangedBox;
  auto box = Augmenter::create(rig, options);
  if (!box) return box.error();
  return WholeAndBoxAugmenters{std::move(*whole), std::move(*box)};
}

}  // namespace augrig::test
