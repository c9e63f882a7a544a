// The command line's shared pieces that commands build on: frame_record() hands the recorder what
// the augmenter made, whole or as changed boxes, and the recording reads back the whole augmented
// images either way (against the augmenter's whole-image output, byte for byte); the PNG outputs
// are whole images from either output.
#include "app/cli.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"
#include "tests/support/gl_test.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::app {
namespace {

class CliTest : public test::GlTest {};

TEST_F(CliTest, FrameRecordOfEitherOutputRecordsTheWholeAugmentedImages) {
  const Rig rig = Rig::paper_default();
  auto augmenters = test::whole_and_box_augmenters(rig, AugmentOptions{});
  ASSERT_TRUE(augmenters) << augmenters.error().message;
  Augmenter &whole = *augmenters->whole, &box = *augmenters->box;
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  const SceneState scene =
      scene_at_contact(rig, whole.boom_model().dims, receptacle, BoomArticulation{0.5, 0.05, 3.0});
  StereoFrame sf;
  sf.left = test::gradient_frame(rig.left().model, PixelFormat::kBayerRG8, CameraId::kLeft);
  sf.right = test::gradient_frame(rig.right().model, PixelFormat::kBayerRG8, CameraId::kRight);
  sf.left.t_ns = sf.right.t_ns = sf.t_key_ns = 1'000'000'000;
  StereoResult w, b;
  ASSERT_TRUE(whole.augment(sf, scene, w));
  ASSERT_TRUE(box.augment(sf, scene, b));

  // The box output goes to the recorder as boxes, the whole one as whole images.
  recorder::FrameRecord from_box = frame_record(b);
  recorder::FrameRecord from_whole = frame_record(w);
  for (int c = 0; c < 2; ++c) {
    ASSERT_TRUE(from_box.augmented_box[c].has_value());
    EXPECT_EQ(*from_box.augmented_box[c], (c == 0 ? b.left : b.right).augmented_box);
    EXPECT_LT(from_box.augmented[c].width(), rig.cameras[c].model.width_px);
    EXPECT_FALSE(from_whole.augmented_box[c].has_value());
    EXPECT_TRUE(pixels_equal(from_box.mask[c], from_whole.mask[c]));
  }
  ASSERT_TRUE(from_box.stats.has_value());
  EXPECT_EQ(from_box.stats->boom_px_left, w.stats.boom_px_left);

  const std::string dir = test::output_dir("app/cli_frame_record");
  auto rec = recorder::Recorder::create(dir, recorder::RecordingInfo{});
  ASSERT_TRUE(rec) << rec.error().message;
  from_box.raw = sf;
  from_whole.raw = sf;
  from_whole.raw.pair_sequence = 1;
  ASSERT_TRUE((*rec)->push(std::move(from_box)));
  ASSERT_TRUE((*rec)->push(std::move(from_whole)));
  ASSERT_TRUE((*rec)->close());
  auto rd = recorder::RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  ASSERT_EQ((*rd)->frame_count(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    SCOPED_TRACE(i == 0 ? "from the box output" : "from the whole output");
    auto f = (*rd)->read_frame(i, recorder::kPartsAll);
    ASSERT_TRUE(f) << f.error().message;
    EXPECT_TRUE(pixels_equal(f->augmented[0], w.left.augmented));
    EXPECT_TRUE(pixels_equal(f->augmented[1], w.right.augmented));
  }

  // The PNG outputs are whole images from the box output too.
  const fs::path out = dir + "/png";
  for (const char* sub : {"left/augmented", "right/augmented", "left/mask", "right/mask", "vis/boom_overlap",
                          "vis/occlusion_left", "vis/occlusion_right", "vis/stereo_classes"})
    fs::create_directories(out / sub);
  write_frame_outputs(out, {"l", "r"}, sf, b);
  const cv::Mat png = cv::imread((out / "left/augmented/l.png").string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(png.cols, rig.left().model.width_px);
  EXPECT_EQ(png.rows, rig.left().model.height_px);
}

}  // namespace
}  // namespace augrig::app
