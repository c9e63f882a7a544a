// slurm: a campaign's tasks as Slurm array jobs (docs/CAMPAIGN.md, "On a cluster"). Each array
// task runs `augrig campaign task MANIFEST ID` (campaign/task.hpp); the array's resources come from
// the measured cost of its tasks. Arrays larger than the cluster's MaxArraySize are cut into
// several scripts, each adding its offset to SLURM_ARRAY_TASK_ID.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "campaign/campaign.hpp"

namespace augrig::campaign {

// Task ids as Slurm's --array list, "0-3,7,9-12", with "%N" when `max_running` > 0.
std::string array_spec(const std::vector<std::size_t>& indices, int max_running);

// Task ids cut into arrays whose indices (id - offset) stay below `max_array_size`.
struct ArrayChunk {
  std::size_t offset = 0;
  std::vector<std::size_t> indices;  // id - offset, ascending
};
std::vector<ArrayChunk> array_chunks(const std::vector<std::size_t>& ids, int max_array_size);

// What one array asks for: the most any of its tasks needs.
struct Resources {
  int cpus = 1;
  std::int64_t mem_mb = 256;
  double time_s = 60;
};
Resources task_resources(const Manifest& m, const std::vector<std::size_t>& ids);

// The sbatch script for one chunk.
std::string sbatch_script(const Manifest& m, const ArrayChunk& chunk, const Resources& r);

// Writes one script per chunk as OUT/slurm/<stem>-<k>.sbatch; returns their paths.
Expected<std::vector<std::filesystem::path>> write_scripts(const Manifest& m,
                                                           const std::vector<std::size_t>& ids,
                                                           const std::string& stem);

// `sbatch --parsable SCRIPT`: the job id, or an Error with sbatch's message. Appends a line to
// OUT/jobs.log (time, job, script).
Expected<std::string> submit(const Manifest& m, const std::filesystem::path& script);

// Runs a program with arguments, capturing stdout+stderr; the exit status (-1: could not start).
struct ProgramResult {
  int status = -1;
  std::string output;
};
ProgramResult run_program(const std::vector<std::string>& argv);

}  // namespace augrig::campaign
