// NumPy .npy files (format version 1.0) of little-endian float32 arrays: what vision tools read
// with one call (`numpy.load`). augrig writes its per-pixel ground truth (receiver depth, stereo
// correspondence) this way, exactly, with NaN where there is none, and reads it back (tests,
// evaluation). https://numpy.org/doc/stable/reference/generated/numpy.lib.format.html
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/expected.hpp"

namespace augrig {

struct NpyArray {
  std::vector<std::int64_t> shape;  // C order (rows first)
  std::vector<float> values;        // prod(shape) values
};

// Writes `values` (prod(shape) of them) as '<f4', C order. Errors name the file.
Status write_npy_f32(const std::string& path, const std::vector<std::int64_t>& shape, const float* values);

// Reads a version 1.x or 2.x .npy file of '<f4' in C order. Errors name the file and what was
// expected (another dtype, Fortran order, a truncated file).
Expected<NpyArray> read_npy_f32(const std::string& path);

}  // namespace augrig
