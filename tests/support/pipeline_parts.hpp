// A pipeline's parts over a real source, for the tests that run the pipeline: the simulated
// flight with its truth as the poses (sim://), or a recording with its recorded rig and poses
// (replay://). The source is opened and started; the caller adds sinks, limits and runs it.
#pragma once

#include <string>

#include "pipeline/pipeline.hpp"

namespace augrig::test {

// Failures are gtest failures (EXPECT), the parts then being incomplete.
pipeline::PipelineParts pipeline_parts(const std::string& uri);

}  // namespace augrig::test
