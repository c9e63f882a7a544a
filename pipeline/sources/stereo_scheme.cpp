// stereo:[tolerance_us=US,mode=timestamp|trigger_id,clock=separate|shared,queue=N]//{LEFT}{RIGHT}:
// two cameras (aravis:// or v4l2:// URIs, camera_scheme.cpp) as a stereo rig, paired as a rig's
// `pairing` section says, with its defaults and ranges (render/rig.hpp: tolerance 2000 us,
// timestamp, separate clocks, a queue of 8 frames). A rig whose cameras carry `source` keys opens
// as this scheme (open_sources' right_uri).
#include <algorithm>

#include "pipeline/sources/schemes.hpp"
#include "render/rig.hpp"

namespace augrig::pipeline {

// stereo:[PAIRING]//{LEFT}{RIGHT}: two cameras, paired as a rig's pairing section says.
Expected<OpenedSource> open_stereo(const SourceUri& u) {
  OpenedSource out;
  if (Status s = u.check_known({"tolerance_us", "mode", "clock", "queue"}); !s) return s.error();
  // The same parameters, defaults and values as a rig's `pairing` section.
  const RigPairing defaults;
  // The rig's pairing section takes the same ranges (render/rig.cpp).
  auto tol = u.get_number("tolerance_us", defaults.tolerance_us, 0, kMaxPairingToleranceUs);
  auto queue = u.get_integer("queue", defaults.queue, 1, 1024);
  if (!tol) return tol.error();
  if (!queue) return queue.error();
  const std::string mode = u.get("mode", defaults.mode), clock = u.get("clock", defaults.clock);
  if (!RigPairing::known_mode(mode))
    return uri_error(u, "mode: expected timestamp or trigger_id, got '" + mode + "'");
  if (!RigPairing::known_clock(clock))
    return uri_error(
        u, "clock: expected separate (each camera its own clock) or shared (PTP), got '" + clock + "'");
  StereoPairerConfig& p = out.options.pairing;
  p.mode = mode == "timestamp" ? PairingMode::kTimestamp : PairingMode::kTriggerId;
  p.tolerance_ns = static_cast<std::int64_t>(*tol * 1e3);
  p.device_clock_shared = clock == "shared";
  // Separate device clocks are compared on host time, through each camera's estimated offset.
  if (!p.device_clock_shared) p.clock_offsets = ClockOffsetConfig{};
  out.options.queue_frames = static_cast<std::size_t>(std::max<long long>(1, *queue));
  out.live = true;
  for (int i = 0; i < 2; ++i) {
    auto cam = open_camera(u.children[i], i == 0 ? CameraId::kLeft : CameraId::kRight);
    if (!cam) return cam.error();
    out.sources.push_back(std::move(*cam));
  }
  return out;
}

}  // namespace augrig::pipeline
