// noise_level: a camera's sensor noise as a noise level function (NLF), estimated from its own
// frames. The variance of a pixel's value about its expected value I (DN) is
//     sigma^2(I) = a * I + b        (DN^2)
// per colour channel: a is the shot (Poissonian) part, b the read (Gaussian) part (Foi,
// Trimeche, Katkovnik & Egiazarian, IEEE TIP 2008). Bayer mosaics are measured per site colour
// on the raw mosaic (R and B on their site planes, G on the quincunx of both green sites), RGB
// per channel (RGBA's alpha is ignored), Mono8 as one channel.
//
// Quantisation: the NLF is the noise before the 8-bit rounding. The camera's 8-bit values carry
// 1/12 DN^2 more (rounding of a noisy value); the fit subtracts it, so that a renderer that adds
// N(0, variance()) to a continuous value and then rounds (render/camera_look) gives back the
// variance measured in the camera's frames.
//
// Method. Each same-colour lattice is cut into blocks of block_px x block_px lattice pixels: a
// plane (RGB or Mono channel; a Bayer R or B site at stride 2) into squares, the Bayer green
// quincunx (both green sites, a square lattice along the image's diagonals, 1.41 px apart) into
// diamonds (those that cross the image's edge are left out). Per block, three numbers:
//   v  the noise variance from Immerkaer's (1996) high-pass [1 -2 1] (x) [1 -2 1] on the block's
//      interior: v = sum(r^2) / (36 n). The mask cancels every signal of the form f(x) + g(y)
//      (ramps, quadratics, horizontal and vertical edges) and nearly all smooth texture.
//   L  the block's level: its mean weighted as v weights the pixels, so that for any signal the
//      mask cancels E[v] = a L + b exactly, even where the level varies inside the block.
//   t  the full-band noise variance: the variance about a least-squares plane (texture detector).
// On the quincunx the two green sites' imbalance (gain, black level) is a checkerboard, which the
// mask passes at full gain: each block's checkerboard component is taken out of v (v = (sum(r^2)
// - (sum(r c))^2 / n) / tr Q, c = +-1 alternating, Q the form's matrix) and of t (B^2 - 4 dof).
// Blocks with a pixel <= clip_low_dn or >= clip_high_dn are rejected as clipped when added. The
// others go into level bins, each a bounded reservoir (a uniform sample over all frames).
// The fit finds, per bin, the noise-only population by a fixed-point iteration seeded at the
// bin's 2 % least-textured blocks: keep the blocks whose t is below its 99 % and v below its
// 99.9 % noise quantile about the bin's current references, and whose level is at least
// clip_margin_sigma sigmas from the clip levels (nearer ones lose their high excursions to the
// clip test and would read low); the new references are the kept blocks' medians corrected to
// means. The quantiles come from the noise distributions of t (chi^2 with B^2 - 3 dof) and of v
// (a weighted sum of chi^2_1, matched to a shifted chi^2 by its first three cumulants, Pearson
// 1959; median within 0.5 %). Texture is judged against the bin's reference, never against a
// block's own v, so chance-low noise blocks are not favoured, and the thresholds sit in the
// noise tails, so the kept noise blocks stay unbiased (to about 0.5 %).
// A bin is used when it keeps min_blocks_per_bin blocks and its full-band / high-pass ratio
// lies within max_band_ratio of 1 (white noise gives 1; texture or correlated noise do not). A
// weighted least-squares line through the bins (weights blocks / sigma^4, iterated on the
// fitted variance) gives a and b, with a >= 0 and b >= 0 enforced by refitting on the active
// constraint. Texture that passes for noise only ever raises a bin, so a bin more than 3 standard
// errors above the line (its blocks' sampling error, plus 1 % for the model) is dropped, the worst
// first, and the line refitted, while min_bins remain. A second pass rescales each block's
// thresholds by the line at its own level and refits. With fewer than min_bins usable levels (or
// all within half a bin), shot and read noise cannot be told apart: a = 0 and b = the measured
// variance, and the report's note says so.
//
// Limits: noise is assumed white (raw sensor data); demosaiced or denoised RGB has spatially
// correlated noise, and its bins fail the band-ratio test (fit()'s error says so). Fine
// texture of about one noise sigma or less in amplitude is indistinguishable from noise in a
// block and reads as extra noise where it covers most of a level; stronger texture is rejected.
// "Fine" is relative to the lattice: periods under ~3 px on a plane at 1 px, but up to ~8 px on
// a Bayer R or B site plane (2 px apart), against ~5 px on G's quincunx. On the demo flight's
// BayerRG8 frames (true a 0.12, b 2.25; 16-frame fits) the woods' texture made G read a 0.106,
// b 4.5 on the site planes (sigma at 30 DN +15 %, at 100 DN +3 %) and reads a 0.117, b 2.9 on the
// quincunx (+4 %, +1 %); R and B still read sigma +4 to 6 % at 30 DN.
//
// Cost (one core, 1280 x 960): add() about 2 ms for Mono8, 2.5 ms for Bayer (the quincunx's
// diagonal reads: ~15 % more than four site planes), 6 ms for RGB8; fit() 5 to 15 ms with full
// reservoirs. Not thread-safe: a caller that adds on the frame thread and fits elsewhere locks
// both, or fits a copy (a few MB at most).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "core/image.hpp"

namespace augrig {

struct NoiseLevelFunction {
  int channels = 0;           // 1 (Mono8) or 3 (R, G, B: RGB channels or Bayer site colours)
  std::array<double, 3> a{};  // shot-noise slope per channel, DN
  std::array<double, 3> b{};  // read-noise variance per channel, DN^2 (before 8-bit rounding)
  // sigma^2 at expected level `level_dn` in channel `ch` (0 for Mono8), never negative; 0 for a
  // channel it does not have (ch < 0, e.g. RGBA's alpha, or ch >= channels).
  double variance(int ch, double level_dn) const;
  bool empty() const { return channels == 0; }
  friend bool operator==(const NoiseLevelFunction&, const NoiseLevelFunction&) = default;
};

// The channel whose NLF applies to pixel (x, y) of an image of format `f`, channel `c` of the
// pixel (0 for Mono8 and Bayer): Bayer -> the site's colour, RGB -> c, Mono8 -> 0.
// RGBA's alpha (c = 3) has no noise: -1.
int noise_channel(PixelFormat f, int x, int y, int c);

struct NoiseEstimateOptions {
  int block_px = 8;  // block side in pixels of one same-colour plane, 6..64 (smaller: v too skewed)
  int bins = 16;     // level bins over 0..255
  int min_blocks_per_bin = 8;
  int min_bins = 2;        // bins needed per channel for a fit (>= 2 distinct levels)
  double clip_low_dn = 4;  // blocks whose pixels reach these levels are left out (clipped noise)
  double clip_high_dn = 251;
  int max_blocks_per_bin = 4096;    // reservoir size per bin and channel (bounds memory and fit())
  double clip_margin_sigma = 4;     // blocks whose level is nearer the clip levels are left out
  double max_band_ratio = 2;        // a bin's full-band / high-pass variance must lie in [1/r, r]
  bool remove_quantisation = true;  // subtract the 1/12 DN^2 of 8-bit rounding from b
};

// What one fit used and found, per channel, for status lines and recordings. Block counts are
// over all frames added (scaled up from the reservoirs once those are full).
struct NoiseFitReport {
  NoiseLevelFunction nlf;
  std::array<int, 3> bins_used{};
  std::array<std::uint64_t, 3> blocks_used{};
  std::uint64_t blocks_seen = 0;
  std::uint64_t blocks_rejected_texture = 0;
  std::uint64_t blocks_rejected_clipped = 0;             // clipped pixels, or a level within the clip margin
  std::array<double, 3> level_min_dn{}, level_max_dn{};  // levels of the bins used (fit's support)
  std::array<double, 3> band_ratio{};  // full-band / high-pass variance over the bins used (1: white)
  std::string note;  // why a channel fell back (too few levels to tell shot from read noise), or empty
};

// Per-bin accumulator of block statistics; frames add into it, fits read it.
class NoiseLevelEstimator {
 public:
  explicit NoiseLevelEstimator(NoiseEstimateOptions options = {});
  // Adds one frame's blocks (any PixelFormat; the format must not change between frames).
  Status add(const Image& image);
  // Fits a and b per channel from what has been added; an error names what is missing.
  Expected<NoiseFitReport> fit() const;
  // Forgets every frame (and the format).
  void clear();
  std::uint64_t frames() const { return frames_; }

  // One block's statistics (see the method above).
  struct BlockStat {
    float level = 0, v = 0, t = 0;
  };

 private:
  struct Bin {
    std::vector<BlockStat> samples;  // bounded reservoir, a uniform sample of the bin's blocks
    std::uint64_t blocks = 0;        // blocks ever added to the bin
  };
  struct Plane {
    int x0, y0, step, byte, channel;  // step 0: the Bayer green quincunx from (x0, y0)
  };
  void add_plane(const Image& image, const Plane& p);
  void add_block(int channel, const BlockStat& s);

  NoiseEstimateOptions options_;
  int channels_ = 0;
  PixelFormat format_ = PixelFormat::kMono8;
  std::array<std::vector<Bin>, 3> bins_;
  std::array<std::uint64_t, 3> seen_{}, clipped_{};  // per channel
  std::uint64_t frames_ = 0;
  static constexpr std::uint64_t kRngSeed = 0x9e3779b97f4a7c15ULL;
  std::uint64_t rng_state_ = kRngSeed;  // reservoir sampling, deterministic
  std::vector<int> weight_;             // level weight per block column/row
};

// One frame's estimate: NoiseLevelEstimator over that frame alone.
Expected<NoiseFitReport> estimate_noise_level(const Image& image, const NoiseEstimateOptions& options = {});

}  // namespace augrig
