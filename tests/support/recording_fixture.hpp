// A small recording written through recorder::Recorder from frames the real augmenter augments
// here (raw, augmented, masks, poses, statistics: everything the recorder stores), for the tests
// of the commands that read recordings (check, replay, export), and copies of it cut short.
#pragma once

#include <cstdint>
#include <string>

#include "core/frame.hpp"
#include "render/rig.hpp"

namespace augrig::test {

inline constexpr int kRecordingFrames = 8;
inline constexpr TimestampNs kRecordingT0 = 2'000'000'000;   // the first pair's time
inline constexpr TimestampNs kRecordingPeriod = 33'000'000;  // between pairs

// The paper's rig with 128 x 96 pinhole cameras (56 deg wide): small frames, quick tests.
Rig small_rig();
// Camera `c`'s raw Mono8 frame `i`: a ramp with noise seeded by (i, c).
Image raw_image(int i, int c);
// Writes `frames` stereo pairs (kRecordingT0 + i * kRecordingPeriod) into the recording folder
// `dir`, the boom articulated differently in each of 8 frames; returns `dir`. Failures are gtest
// failures of the calling test.
std::string write_recording(const std::string& dir, int frames = kRecordingFrames);
// The recording "build/test-output/PREFIX<test name>/rec" of `frames` pairs, written on the first
// call in this process. CTest runs each test in its own process, in parallel: one per test.
const std::string& recording_of_this_test(const std::string& prefix, int frames = kRecordingFrames);
// The first `bytes` of `from`'s database in output_dir(name), as `head -c` leaves a file copied
// half-way; returns that folder.
std::string truncated_copy(const std::string& from, const std::string& name, std::uintmax_t bytes);

}  // namespace augrig::test
