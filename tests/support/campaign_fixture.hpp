// The flights campaign tests run on, and the unsharded runs their merged reports must equal
// (tests/campaign/merge_test.cpp, tests/app/cmd_campaign_test.cpp).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace augrig::test {

// A file's lines, without their '\n'.
std::vector<std::string> lines_of(const std::filesystem::path& p);
// CSV rows without the columns whose header names end in `_ms` (wall times differ from run to run).
std::vector<std::string> without_time_columns(const std::vector<std::string>& rows);

// Two simulated recordings (a: 4 s, 41 stereo frames; b: 3 s, 31), a fresh folder per test
// (SUITE_TEST under build/test-output) and in it boom.csv, a boom script that moves all the time:
// a shard that restarted the script's clock would differ.
class CampaignFlights : public ::testing::Test {
 protected:
  std::filesystem::path dir;
  std::string rec_a, rec_b;
  void SetUp() override;
  // The merged reports under `report` (REPORT/VARIANT/FLIGHT/...) against unsharded runs of flight
  // `f` (rec_a or rec_b): `augrig evaluate` with the boom script and `eval_flags` for variant "eval", and
  // (`stats`) `augrig replay`'s statistics for variant "stats". Row for row: stats.csv, evaluation.csv,
  // evaluation_sums.csv (but for its times), and the evaluation table but for its title.
  void expect_equals_unsharded(const std::filesystem::path& report, const std::string& f,
                               const std::string& eval_flags = "--every 3", bool stats = true);
};

}  // namespace augrig::test
