// Helpers shared by the tests: where test data lives and where outputs (diff images) go, and
// comparisons several suites make.
#pragma once

#include <string>
#include <vector>

#include "core/frame.hpp"
#include "nav/types.hpp"
#include "render/augmenter.hpp"
#include "render/camera_model.hpp"

namespace augrig::test {

// Absolute path of a file under tests/data.
std::string data_path(const std::string& relative);
// A fresh directory under build/test-output/<name> (created, emptied). Removed again when the test
// program ends with every test passed (a failed test's outputs, diff images among them, stay), so
// that a whole run does not fill the disk; AUGRIG_KEEP_TEST_OUTPUT=1 keeps them all.
std::string output_dir(const std::string& name);
// Path of the built augrig binary.
std::string augrig_binary();
// Runs a shell command, returns its exit status and fills `output` with stdout+stderr.
int run_command(const std::string& command, std::string* output = nullptr);
// Runs the augrig binary with `args`; `output` gets its stdout and stderr together.
int run_augrig(const std::string& args, std::string* output = nullptr);
// A recording of the simulated flight tests/data/SCENARIO (every K-th frame), made once with
// `augrig run --record` under build/test-output/recordings/NAME and reused; "" (and `why`) when
// augrig fails. Test processes running at once take turns under a lock.
std::string sim_recording(const std::string& scenario, int every, const std::string& name, std::string* why);
// npm packages (`packages`: "name@version" each) installed once into build/test-output/npm-NAME and
// kept between runs, with tests/support/SCRIPT copied next to them; returns the script's path, or
// "" with `why` when node or npm cannot provide them. Test processes running at once (CTest -j)
// take turns under a lock, and a folder counts as installed only after an install finished.
std::string npm_script(const std::string& name, const std::vector<std::string>& packages, const std::string& script,
                       std::string* why);
// Every field of two GPS fixes but the arrival time, exactly (one parser's output against another's);
// `what` names the fix in failure messages.
void expect_same_fix(const nav::GpsFix& got, const nav::GpsFix& want, const std::string& what);

// A raw frame of camera `id` the size of `cm`, in `fmt`, filled with a gradient and an XOR pattern
// (every byte differs from its neighbours'): what the augmenter tests composite over.
Frame gradient_frame(const CameraModel& cm, PixelFormat fmt, CameraId id);

// Two augmenters of `rig` with `options` but for AugmentOptions::augmented_output: one makes whole
// augmented images, the other only their changed boxes. For tests that compare the two forms.
struct WholeAndBoxAugmenters {
  std::unique_ptr<Augmenter> whole, box;
};
Expected<WholeAndBoxAugmenters> whole_and_box_augmenters(const Rig& rig, AugmentOptions options);

}  // namespace augrig::test
