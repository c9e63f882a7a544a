// The receiver's trajectory in the left camera as a sink, in the TUM RGB-D benchmark's format
// (`timestamp tx ty tz qx qy qz qw`, metres, Hamilton quaternion, one line per pair), which
// trajectory tools read directly (evo's `evo_traj tum`, the TUM scripts): the truth to score a
// pose estimator run on the same frames against. The time is the pair's on the nav clock (GPS)
// where the poses map frames onto it, else its key time, in seconds. Pairs without a receiver
// (no pose, receiver absent) are left out; the file is flushed per line.
#include <fstream>
#include <iomanip>

#include "pipeline/sinks/registry.hpp"

namespace augrig::pipeline {

namespace {

class TumSink final : public FrameSink {
 public:
  TumSink(std::string path, Pose T_cam_body) : path_(std::move(path)), T_cam_body_(T_cam_body) {}

  Status open() {
    out_.open(path_, std::ios::binary);
    if (!out_) return make_error("tum sink: ", path_, ": cannot write the file");
    out_ << "# augrig: the receiver's pose in the left camera (OpenCV frame), per pair\n"
         << "# timestamp_s tx_m ty_m tz_m qx qy qz qw\n";
    return {};
  }

  Status consume(PairContext& pair) override {
    if (!pair.scene || !pair.scene->receiver_present) return {};
    const Pose T_cam_receiver = T_cam_body_ * pair.scene->T_body_receiver;
    const TimestampNs t_ns = pair.poses.t_nav_ns.value_or(pair.raw.t_key_ns);
    const Eigen::Quaterniond& q = T_cam_receiver.rotation;
    const Eigen::Vector3d& t = T_cam_receiver.translation_m;
    if (t_ns < 0) out_ << '-';  // whole seconds and nanoseconds, exact at GPS times' 19 digits
    const TimestampNs abs_ns = t_ns < 0 ? -t_ns : t_ns;
    out_ << abs_ns / 1'000'000'000 << '.' << std::setw(9) << std::setfill('0') << abs_ns % 1'000'000'000
         << std::setfill(' ') << std::setprecision(9) << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' '
         << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
    out_.flush();
    if (!out_) return make_error("tum sink: ", path_, ": write failed");
    return {};
  }

 private:
  std::string path_;
  Pose T_cam_body_;
  std::ofstream out_;
};

}  // namespace

Expected<std::unique_ptr<FrameSink>> make_tum_sink(const std::string& arg, const SinkSetup& setup) {
  auto sink = std::make_unique<TumSink>(arg, setup.rig.cameras.at(0).T_body_cam.inverse());
  if (Status st = sink->open(); !st) return st.error();
  return std::unique_ptr<FrameSink>(std::move(sink));
}

}  // namespace augrig::pipeline
