#include "capture/stereo_pairer.hpp"

#include <gtest/gtest.h>

namespace augrig {
namespace {

Frame make(CameraId cam, TimestampNs t, std::uint64_t seq) {
  Frame f;
  f.camera = cam;
  f.t_ns = t;
  f.sequence = seq;
  f.clock = ClockDomain::kSim;
  return f;
}

TEST(StereoPairer, PairsWithinToleranceAndRecordsSkew) {
  StereoPairer p(1'000'000);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 100'000'000, 0)));
  auto sf = p.push(make(CameraId::kRight, 100'400'000, 0));
  ASSERT_TRUE(sf);
  EXPECT_EQ(sf->skew_ns, 400'000);
  EXPECT_EQ(sf->t_key_ns, 100'200'000);
  EXPECT_EQ(sf->left.camera, CameraId::kLeft);
  EXPECT_EQ(sf->right.camera, CameraId::kRight);
  EXPECT_EQ(p.stats().pairs, 1u);
  EXPECT_EQ(p.stats().max_abs_skew_ns, 400'000);
}

TEST(StereoPairer, RightFirstAlsoPairs) {
  StereoPairer p(1'000'000);
  EXPECT_FALSE(p.push(make(CameraId::kRight, 50, 0)));
  auto sf = p.push(make(CameraId::kLeft, 60, 0));
  ASSERT_TRUE(sf);
  EXPECT_EQ(sf->skew_ns, -10);
}

TEST(StereoPairer, DroppedFrameIsCountedNotPairedWithTheWrongPartner) {
  const std::int64_t period = 33'333'333;
  StereoPairer p(2'000'000);
  int pairs = 0;
  for (int i = 0; i < 10; ++i) {
    if (i != 4) pairs += p.push(make(CameraId::kLeft, i * period, i)).has_value();  // left frame 4 lost
    auto sf = p.push(make(CameraId::kRight, i * period + 500'000, i));
    if (sf) {
      ++pairs;
      EXPECT_EQ(sf->left.sequence, sf->right.sequence);
    }
  }
  p.flush();
  EXPECT_EQ(pairs, 9);
  EXPECT_EQ(p.stats().unpaired_right, 1u);
  EXPECT_EQ(p.stats().unpaired_left, 0u);
}

TEST(StereoPairer, OutOfOrderAndDuplicateFramesAreRejected) {
  StereoPairer p(1000);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 5000, 1)));
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 5000, 2)));  // duplicate timestamp
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 4000, 3)));  // goes back in time
  EXPECT_EQ(p.stats().unpaired_left, 2u);
  EXPECT_TRUE(p.push(make(CameraId::kRight, 5100, 1)));
}

TEST(StereoPairer, BoundedPendingQueue) {
  StereoPairer p(10, 3);
  for (int i = 0; i < 10; ++i) EXPECT_FALSE(p.push(make(CameraId::kLeft, i * 1000, i)));
  EXPECT_EQ(p.stats().unpaired_left, 7u);  // only 3 kept
  p.flush();
  EXPECT_EQ(p.stats().unpaired_left, 10u);
}

}  // namespace
}  // namespace augrig
