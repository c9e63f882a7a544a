// euroc://DIR[?tolerance_ns=NS&from_frame=N&seek_s=S&left=cam0&right=cam1]: a EuRoC/ASL dataset
// (recorder/euroc.hpp), ours or anyone's. Its left and right streams' frames pair by identical
// timestamps (tolerance_ns allows skew), from pair N or S seconds in; left and right choose other
// streams (cam0_augmented, cam0_mask). Lockstep: each pair's left Frame, then its right one, as
// fast as read.
#include "pipeline/sources/schemes.hpp"
#include "recorder/euroc.hpp"

namespace augrig::pipeline {

Expected<OpenedSource> open_euroc(const SourceUri& u) {
  OpenedSource out;
  if (Status s = u.check_known({"tolerance_ns", "from_frame", "seek_s", "left", "right"}); !s)
    return s.error();
  recorder::EurocOptions eo;
  auto tol = u.get_integer("tolerance_ns", 0, 0, 1LL << 40);
  if (!tol) return tol.error();
  eo.pair_tolerance_ns = *tol;
  eo.left_stream = u.get("left", "cam0");
  eo.right_stream = u.get("right", "cam1");
  auto start = playback_start(u);
  if (!start) return start.error();
  eo.start_pair = start->frame;
  eo.start_offset_ns = start->offset_ns;
  auto src = recorder::EurocSource::open(u.target, eo);
  if (!src) return src.error();
  out.options.lossless = true;
  out.options.skip_read_errors = true;  // an unreadable image skips its pair
  out.options.pairing.mode = PairingMode::kAdjacent;
  out.sources.push_back(std::move(*src));
  return out;
}

}  // namespace augrig::pipeline
