// Writes fuzz_mcap's seeds (tests/data/fuzz/fuzz_mcap/): an MCAP file of the five messages
// McapSource decodes, twice, through McapWriter, in one chunk or in chunks of 200 bytes, and each
// message on its own (selector byte 1). Built with the fuzz targets:
//   build-fuzz/fuzz/make_mcap_seeds tests/data/fuzz/fuzz_mcap
#include <cstdio>
#include <fstream>

#include "recorder/mcap_writer.hpp"
#include "ros2/messages.hpp"
using namespace augrig;
namespace {

// One MCAP file into `out` (selector byte 0 first); with `messages_dir`, each message alone too.
int write_seed(const std::string& out, std::size_t chunk_size_bytes, const std::string& messages_dir) {
  const std::string file = out + ".mcap";
  recorder::McapWriterOptions o;
  o.chunk_size_bytes = chunk_size_bytes;
  auto w = recorder::McapWriter::create(file, o);
  if (!w) return 1;
  auto& m = **w;
  const auto si = m.add_schema("sensor_msgs/msg/Image", "ros2msg", "x");
  const auto ci = m.add_channel(si, "/left/image_raw", "cdr", {});
  const auto sp = m.add_schema("geometry_msgs/msg/PoseWithCovarianceStamped", "ros2msg", "x");
  const auto cp = m.add_channel(sp, "/left/receiver_pose", "cdr", {});
  const auto st = m.add_schema("tf2_msgs/msg/TFMessage", "ros2msg", "x");
  const auto ct = m.add_channel(st, "/tf_static", "cdr", {});
  const auto ss = m.add_schema("augrig_msgs/msg/OcclusionStats", "ros2msg", "x");
  const auto cs = m.add_channel(ss, "/augrig/stats", "cdr", {});
  const auto sf = m.add_schema("augrig_msgs/msg/StereoFrameInfo", "ros2msg", "x");
  const auto cf = m.add_channel(sf, "/augrig/frame", "cdr", {});
  Image im(4, 3, PixelFormat::kRGB8);
  Pose p;
  p.translation_m = {1, 2, 3};
  OcclusionStats s;
  s.receiver_px_left = 5;
  const ros2::StereoFrameInfo fi;
  bool ok = true;
  for (int k = 0; k < 2; ++k) {
    const std::int64_t t = 1000 + k * 100;
    s.t_ns = t;
    ok = ok && m.write_message(ci, t, ros2::image(t, "left_camera", im.cview())) &&
         m.write_message(cp, t, ros2::pose_with_covariance(t, "left_camera", p, {})) &&
         m.write_message(ct, t, ros2::tf_message({{t, "tanker_body", "left_camera", p}})) &&
         m.write_message(cs, t, ros2::occlusion_stats(t, s)) &&
         m.write_message(cf, t, ros2::stereo_frame_info(t, fi));
  }
  if (!messages_dir.empty()) {
    s.t_ns = 5;
    const std::pair<const char*, std::vector<std::uint8_t>> raw[] = {
        {"image", ros2::image(1, "left_camera", im.cview())},
        {"pose", ros2::pose_with_covariance(1, "l", p, {})},
        {"tf", ros2::tf_message({{1, "a", "b", p}})},
        {"stats", ros2::occlusion_stats(1, s)},
        {"frame", ros2::stereo_frame_info(1, fi)}};
    for (const auto& [n, b] : raw) {
      std::ofstream f(messages_dir + "/msg_" + n, std::ios::binary);
      f.put(1);
      f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    }
  }
  if (!ok || !m.write_metadata("augrig", {{"rig_yaml", "cameras: []"}})) return 2;
  if (!m.close()) return 2;
  std::ifstream in(file, std::ios::binary);
  std::ofstream seed(out, std::ios::binary);
  seed.put(0);
  seed << in.rdbuf();
  in.close();
  std::remove(file.c_str());
  return seed ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_mcap_seeds DIR\n");
    return 1;
  }
  const std::string dir = argv[1];
  if (int rc = write_seed(dir + "/one_chunk", 4u << 20, dir)) return rc;
  return write_seed(dir + "/many_chunks", 200, "");
}
