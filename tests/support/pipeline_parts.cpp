#include "tests/support/pipeline_parts.hpp"

#include <gtest/gtest.h>

#include "pipeline/sources.hpp"
#include "recorder/replay_source.hpp"

namespace augrig::test {

pipeline::PipelineParts pipeline_parts(const std::string& uri) {
  using namespace pipeline;
  auto opened = open_sources(uri);
  EXPECT_TRUE(opened) << opened.error().message;
  PipelineParts p;
  if (!opened) return p;
  if (opened->sim) {
    p.rig = opened->sim->scenario.rig;
    p.poses = sim_truth_poses(*opened->sim);
  } else {
    auto rig = parse_rig(opened->replay->reader().meta("rig_yaml"), "recorded rig");
    EXPECT_TRUE(rig) << rig.error().message;
    if (rig) p.rig = *rig;
    p.poses = recorded_poses(p.rig);
  }
  auto models = load_rig_models(p.rig);
  EXPECT_TRUE(models) << models.error().message;
  if (models) p.models = *models;
  p.source_info = *opened;
  auto stereo = start_stereo(std::move(*opened));
  EXPECT_TRUE(stereo) << stereo.error().message;
  if (stereo) p.source = std::move(*stereo);
  return p;
}

}  // namespace augrig::test
