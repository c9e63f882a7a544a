// The Slurm side of a campaign without a cluster: array lists as Slurm writes them, arrays cut below
// MaxArraySize with their offsets, resources from the measured cost, the script's lines, and
// a missing sbatch. (tests/app/cmd_campaign_test.cpp submits to a real Slurm.)
#include "campaign/slurm.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig::campaign {
namespace {

namespace fs = std::filesystem;

TEST(SlurmArray, ListsRunsAsRanges) {
  EXPECT_EQ(array_spec({0, 1, 2, 3}, 0), "0-3");
  EXPECT_EQ(array_spec({0, 1, 2, 3, 7, 9, 10, 11, 12}, 0), "0-3,7,9-12");
  EXPECT_EQ(array_spec({5}, 4), "5%4");
  EXPECT_EQ(array_spec({}, 0), "");
}

TEST(SlurmArray, ChunksKeepIndicesBelowMaxArraySize) {
  std::vector<std::size_t> ids;
  for (std::size_t i = 0; i < 2500; ++i) ids.push_back(i);
  const auto c = array_chunks(ids, 1001);
  ASSERT_EQ(c.size(), 3u);
  std::size_t n = 0;
  for (const auto& k : c) {
    for (std::size_t i : k.indices) {
      EXPECT_LT(i, 1001u);
      EXPECT_EQ(k.offset + i, ids[n]);  // every id once, in order
      ++n;
    }
  }
  EXPECT_EQ(n, ids.size());
  // Sparse ids (a resume): one chunk while they fit, offsets from the first id of each.
  const auto s = array_chunks({4000, 4003, 4999, 5001, 7, 7}, 1000);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0].offset, 7u);
  EXPECT_EQ(s[0].indices, std::vector<std::size_t>{0});
  EXPECT_EQ(s[1].offset, 4000u);
  EXPECT_EQ(s[1].indices, (std::vector<std::size_t>{0, 3, 999}));
  EXPECT_EQ(s[2].offset, 5001u);
}

Manifest manifest(const fs::path& dir) {
  Manifest m;
  m.file = dir / "manifest.yaml";
  m.name = "study";
  m.out = dir;
  m.augrig = "/opt/augrig/bin/augrig";
  m.slurm.cpus_per_task = 2;
  m.slurm.time_safety = 2;
  m.slurm.partition = "batch";
  m.slurm.extra = {"--qos=long"};
  m.slurm.max_running = 4;
  m.costs = {{"fast", TaskCost{5, 0.1, 500LL << 20, ""}}, {"slow", TaskCost{10, 2.0, 1LL << 30, ""}}};
  for (std::size_t i = 0; i < 4; ++i) {
    Task t;
    t.id = i;
    t.variant = i < 3 ? "fast" : "slow";
    t.flight = "f";
    t.shard.frames = 300;
    m.tasks.push_back(t);
  }
  return m;
}

TEST(SlurmResources, FromTheMeasuredCostOfTheArraysTasks) {
  const Manifest m = manifest(test::output_dir("campaign_slurm_res"));
  // fast: (5 + 300 x 0.1) x 2 + 60 = 130 s; 500 MB x 1.5 + 64.
  const Resources f = task_resources(m, {0, 1, 2});
  EXPECT_EQ(f.cpus, 2);
  EXPECT_DOUBLE_EQ(f.time_s, 130);
  EXPECT_EQ(f.mem_mb, 814);
  // With the slow task the array asks for the most: (10 + 600) x 2 + 60 s, 1 GB x 1.5 + 64.
  const Resources s = task_resources(m, {0, 3});
  EXPECT_DOUBLE_EQ(s.time_s, 1280);
  EXPECT_EQ(s.mem_mb, 1600);
}

TEST(SlurmScript, RunsEachArrayTaskAsACampaignTask) {
  const fs::path dir = test::output_dir("campaign_slurm_script");
  Manifest m = manifest(dir);
  const auto paths = write_scripts(m, {0, 1, 3}, "campaign");
  ASSERT_TRUE(paths) << paths.error().message;
  ASSERT_EQ(paths->size(), 1u);
  std::ifstream in(paths->front());
  const std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const std::string& want : std::vector<std::string>{
           "#!/bin/bash\n", "#SBATCH --job-name=augrig-study\n", "#SBATCH --array=0-1,3%4\n",
           "#SBATCH --cpus-per-task=2\n", "#SBATCH --mem=1600M\n", "#SBATCH --time=0-00:22:00\n",
           "#SBATCH --partition=batch\n", "#SBATCH --qos=long\n",
           "#SBATCH --output=" + (dir / "logs" / "slurm-%A_%a.out").string() + "\n",
           "exec '/opt/augrig/bin/augrig' campaign task '" + m.file.string() +
               "' \"$((0 + SLURM_ARRAY_TASK_ID))\"\n"})
    EXPECT_NE(s.find(want), std::string::npos) << want << "\nin\n" << s;
  EXPECT_TRUE(fs::is_directory(dir / "logs"));  // Slurm does not create it
  // The script is valid bash.
  EXPECT_EQ(test::run_command("bash -n " + paths->front().string()), 0);

  // More tasks than an array may hold: two scripts, the second with its offset.
  m.slurm.max_array_size = 2;
  const auto two = write_scripts(m, {0, 1, 3}, "resume");
  ASSERT_TRUE(two);
  ASSERT_EQ(two->size(), 2u);
  std::ifstream in2(two->back());
  const std::string s2((std::istreambuf_iterator<char>(in2)), std::istreambuf_iterator<char>());
  EXPECT_NE(s2.find("#SBATCH --array=0%4\n"), std::string::npos) << s2;
  EXPECT_NE(s2.find("\"$((3 + SLURM_ARRAY_TASK_ID))\""), std::string::npos) << s2;
}

TEST(SlurmSubmit, WithoutSbatchItSaysWhatToInstall) {
  // sbatch's own refusals are tested on a real Slurm (tests/app/cmd_campaign_test.cpp).
  const fs::path dir = test::output_dir("campaign_slurm_submit");
  const Manifest m = manifest(dir);
  const char* old_path = std::getenv("PATH");
  const std::string saved = old_path ? old_path : "";
  setenv("PATH", dir.c_str(), 1);
  const auto r = submit(m, dir / "x.sbatch");
  setenv("PATH", saved.c_str(), 1);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("cannot run sbatch (is Slurm's client installed: slurm-client?)"),
            std::string::npos)
      << r.error().message;
  EXPECT_FALSE(fs::exists(dir / "jobs.log"));
}

}  // namespace
}  // namespace augrig::campaign
