// sim://SCENARIO (pipeline/sources/sim_scheme.cpp): one source with both cameras, paced or
// lockstep, and what its parameters refuse.
#include <gtest/gtest.h>

#include "pipeline/sources.hpp"

namespace augrig::pipeline {
namespace {

TEST(SimScheme, SimIsOneSourceWithBothCamerasPacedOrLockstep) {
  auto o = open_sources("sim://demo");
  ASSERT_TRUE(o) << o.error().message;
  ASSERT_EQ(o->sources.size(), 1u);
  EXPECT_EQ(o->sources[0]->uri(), "sim://demo");
  EXPECT_EQ(o->scenario, "demo");
  EXPECT_FALSE(o->live);
  EXPECT_FALSE(o->options.lossless) << "real time by default";
  // The demo's cameras stamp clocks 50 us apart: the tolerance covers that and a quarter period.
  EXPECT_GT(o->options.pairing.tolerance_ns, 50'000);
  EXPECT_LT(o->options.pairing.tolerance_ns, 16'000'000);
  o = open_sources("sim://demo?rate=0&every=3");
  ASSERT_TRUE(o);
  EXPECT_TRUE(o->options.lossless);
  // A simulation is finite and knows its length; it plays no range and cannot seek.
  const FrameSource& sim = *o->sources.front();
  EXPECT_TRUE(sim.capabilities().finite);
  EXPECT_FALSE(sim.capabilities().seekable || sim.capabilities().ranged);
  EXPECT_GT(sim.pair_count(), 0u);
  EXPECT_EQ(sim.pair_count(), sim.image_count() / 2);
  EXPECT_FALSE(sim.origin_t_ns());
  EXPECT_FALSE(o->sources.front()->set_range_end(3));
}

TEST(SimScheme, BadBayerAndBoomAreErrorsNamingTheValue) {
  auto o = open_sources("sim://demo?bayer=XY");
  ASSERT_FALSE(o);
  EXPECT_EQ(o.error().message,
            "source URI 'sim://demo?bayer=XY': bayer: expected RG, GR, GB or BG, got 'XY'");
  o = open_sources("sim://demo?boom=real");
  ASSERT_FALSE(o);
  EXPECT_EQ(o.error().message,
            "source URI 'sim://demo?boom=real': boom: expected none or physical, got 'real'");
}

}  // namespace
}  // namespace augrig::pipeline
