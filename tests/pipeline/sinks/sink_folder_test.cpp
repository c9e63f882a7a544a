// SinkFolder: the folder and its subfolders made with the INCOMPLETE marker, removed by complete();
// text, images and links written under it with their folders made on the way (an image read back
// by OpenCV, a link the same bytes); every failure an Error naming the sink and the path.
#include "pipeline/sinks/sink_folder.hpp"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "tests/support/test_support.hpp"

namespace fs = std::filesystem;

namespace augrig::pipeline {
namespace {

std::string text_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(SinkFolder, MarkedIncompleteUntilCompleteAndFilesGoWhereTheySay) {
  const std::string dir = test::output_dir("sink_folder") + "/out";
  const SinkFolder f("kitti sink", dir);
  ASSERT_TRUE(f.create({"images", "labels"}, "removed when the export has finished"));
  EXPECT_TRUE(fs::is_directory(dir + "/images"));
  EXPECT_TRUE(fs::is_directory(dir + "/labels"));
  EXPECT_EQ(text_of(dir + "/INCOMPLETE"), "written by augrig; removed when the export has finished\n");

  ASSERT_TRUE(f.write_text("a/b/calib.txt", "K: 1 0 0\n"));
  EXPECT_EQ(text_of(dir + "/a/b/calib.txt"), "K: 1 0 0\n");
  cv::Mat im(4, 6, CV_8UC3, cv::Scalar(10, 20, 30));
  ASSERT_TRUE(f.write_image("training/image_2/000000_10.png", im));
  const cv::Mat back = cv::imread(dir + "/training/image_2/000000_10.png", cv::IMREAD_UNCHANGED);
  ASSERT_EQ(back.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(back, im, cv::NORM_INF), 0.0);
  ASSERT_TRUE(f.write_image("x.jpg", im, {cv::IMWRITE_JPEG_QUALITY, 50}));
  EXPECT_EQ(cv::imread(dir + "/x.jpg").cols, 6);
  ASSERT_TRUE(f.link("a/b/calib.txt", "c/calib_copy.txt"));
  EXPECT_EQ(text_of(dir + "/c/calib_copy.txt"), "K: 1 0 0\n");
  EXPECT_EQ(f.path("c/calib_copy.txt"), dir + "/c/calib_copy.txt");

  f.complete();
  EXPECT_FALSE(fs::exists(dir + "/INCOMPLETE"));
}

TEST(SinkFolder, FailuresNameTheSinkAndThePath) {
  const std::string dir = test::output_dir("sink_folder_errors");
  std::ofstream(dir + "/file") << "x";
  // A folder where a file stands.
  const SinkFolder blocked("coco sink", dir + "/file/out");
  auto c = blocked.create({}, "removed when the labels are complete");
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().message.rfind("coco sink: " + dir + "/file/out: cannot create the folder: ", 0), 0u)
      << c.error().message;
  const SinkFolder f("yolo sink", dir);
  fs::create_directories(dir + "/taken.txt");  // a folder where the file should go
  auto t = f.write_text("taken.txt", "x");
  ASSERT_FALSE(t);
  EXPECT_EQ(t.error().message, "yolo sink: " + dir + "/taken.txt: cannot write the file");
  auto i = f.write_image("image.unknown_extension", cv::Mat(2, 2, CV_8UC1, cv::Scalar(0)));
  ASSERT_FALSE(i);
  EXPECT_EQ(i.error().message.rfind("yolo sink: " + dir + "/image.unknown_extension: ", 0), 0u)
      << i.error().message;
  auto l = f.link("missing.txt", "linked.txt");
  ASSERT_FALSE(l);
  EXPECT_EQ(l.error().message.rfind("yolo sink: " + dir + "/linked.txt: cannot write the file: ", 0), 0u)
      << l.error().message;
}

}  // namespace
}  // namespace augrig::pipeline
