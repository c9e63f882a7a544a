// sim://SCENARIO[?every=K&rate=R&bayer=RG|GR|GB|BG&boom=none|physical]: the simulated flight's two
// cameras. SCENARIO is a built-in scenario's name, or a scenario file (a path with '/' or ending in
// .yaml). The flight and every sensor are simulated once here, shared by the rendered cameras, the
// simulated nav streams and the truth (OpenedSourceInfo::sim, ::sim_clock, ::scenario).
//   every=K   every K-th frame of each camera (1)
//   rate=R    R times real time (1); 0: as fast as possible, lockstep
//   bayer=..  the cameras deliver raw mosaics of that pattern, as GigE rigs do
//   boom=..   physical: the boom in the simulated scene; none (default): boom-free frames
#include <algorithm>
#include <array>
#include <atomic>
#include <cstdlib>
#include <optional>

#include "core/clock.hpp"
#include "pipeline/sources/schemes.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/sim_clock.hpp"

namespace augrig::pipeline {
namespace {

// sim://SCENARIO: the simulated flight's cameras, rendered on the capture thread that reads them
// by the CPU renderer (sim/synthetic_scene_cpu.hpp: no GL context), paced to real time unless rate=0.
class SimSource final : public FrameSource {
 public:
  SimSource(std::string uri, std::shared_ptr<const SimulatedFlight> sim, int every,
            std::shared_ptr<sim::SimClock> clock, bool physical_boom)
      : uri_(std::move(uri)),
        sim_(std::move(sim)),
        every_(every),
        clock_(std::move(clock)),
        physical_boom_(physical_boom) {}
  std::string uri() const override { return uri_; }
  std::uint64_t frames_dropped() const override { return dropped_; }
  SourceCapabilities capabilities() const override { return {.finite = true}; }
  std::size_t pair_count() const override { return image_count() / 2; }
  // The frames the flight's cameras deliver that every=K selects (as FlightSource selects them).
  std::size_t image_count() const override {
    if (!image_count_) {
      std::size_t n = 0;
      for (const sim::FrameTruth& t : sim::frame_truths(sim_->scenario, *sim_->flight, sim_->logs.cameras))
        n += every_ <= 1 || t.sequence % static_cast<std::uint64_t>(every_) == 0;
      image_count_ = n;
    }
    return *image_count_;
  }

  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds) override {
    if (!source_) {
      auto src = sim::FlightSource::create(
          sim_->scenario, *sim_->flight, sim::frame_truths(sim_->scenario, *sim_->flight, sim_->logs.cameras),
          every_);
      if (!src) return make_error(uri_, ": ", src.error().message);
      source_ = std::move(*src);
      source_->set_physical_boom(physical_boom_);
    }
    if (clock_->paced()) {
      // Live-like: a frame whose time is more than a frame period past is lost, not rendered late
      // (a camera does not wait for its reader); counted with the camera's drops.
      const auto period_ns =
          static_cast<TimestampNs>(1e9 / std::max(1.0, sim_->scenario.sensors.cameras.fps));
      // The decision is taken per exposure (the left frame): its right partner shares its fate, so
      // that a source behind schedule loses whole pairs, not every right frame.
      while (const sim::FrameTruth* next = source_->peek()) {
        const bool late = monotonic_now_ns() > clock_->host_ns(next->t_gps_ns) + period_ns;
        const bool skip = next->camera == 0
                              ? late
                              : next->sequence == skipped_left_ || (late && next->sequence != rendered_left_);
        if (!skip) break;
        if (next->camera == 0) skipped_left_ = next->sequence;
        next_sequence_[next->camera] = next->sequence + static_cast<std::uint64_t>(every_);
        source_->skip();
        ++dropped_;
      }
      if (const sim::FrameTruth* next = source_->peek(); next && next->camera == 0)
        rendered_left_ = next->sequence;
    }
    auto r = source_->read(out, {});
    if (r && *r == ReadStatus::kFrame) {
      // Frames the simulated camera dropped (its timing model), counted as they are passed, as a
      // camera's frame-id gaps are. With every=K only every K-th sequence is delivered.
      std::uint64_t& expect = next_sequence_[index_of(out.camera)];
      if (out.sequence > expect) dropped_ += (out.sequence - expect) / static_cast<std::uint64_t>(every_);
      expect = out.sequence + static_cast<std::uint64_t>(every_);
    }
    if (!r || *r != ReadStatus::kFrame || !clock_->paced()) return r;
    // Real time on the run's clock (shared with the simulated nav streams): a frame is not handed
    // out before its mid-exposure instant.
    const TimestampNs due = clock_->host_ns(source_->last_truth().t_gps_ns);
    clock_->wait_until(source_->last_truth().t_gps_ns);
    const TimestampNs now = monotonic_now_ns();
    out.t_host_ns = std::max(due, now);
    return r;
  }

 private:
  std::string uri_;
  std::shared_ptr<const SimulatedFlight> sim_;
  int every_;
  std::shared_ptr<sim::SimClock> clock_;
  bool physical_boom_ = false;
  std::unique_ptr<sim::FlightSource> source_;
  std::array<std::uint64_t, 2> next_sequence_{};  // per camera: the camera model's own drops show as gaps
  std::atomic<std::uint64_t> dropped_{0};
  mutable std::optional<std::size_t> image_count_;
  std::uint64_t skipped_left_ = ~0ull,
                rendered_left_ = ~0ull;  // sequences  // read by the pipeline while the capture thread counts
};

Expected<sim::Scenario> scenario_of(const SourceUri& u) {
  if (u.target.find('/') != std::string::npos || u.target.ends_with(".yaml"))
    return sim::load_scenario(u.target);
  return sim::builtin_scenario(u.target);
}

}  // namespace

// sim://SCENARIO: the flight simulated once for the cameras, the nav streams and the truth.
Expected<OpenedSource> open_sim(const SourceUri& u) {
  OpenedSource out;
  if (Status s = u.check_known({"every", "rate", "bayer", "boom"}); !s) return s.error();
  auto scenario = scenario_of(u);
  if (!scenario) return uri_error(u, scenario.error().message);
  // bayer=RG|GR|GB|BG: the cameras deliver raw mosaics of that pattern, as GigE rigs do.
  if (u.has("bayer")) {
    auto f = bayer_param(u);
    if (!f) return f.error();
    scenario->sensors.cameras.format = *f;
  }
  // boom=physical: the boom is in the simulated scene (the frames a real boom would give), for
  // comparing augrig's augmentation with it (docs/LOOK.md); boom=none (default): boom-free frames.
  const std::string boom = u.get("boom", "none");
  if (boom != "none" && boom != "physical")
    return uri_error(u, "boom: expected none or physical, got '" + boom + "'");
  auto every = u.get_integer("every", 1, 1, 1'000'000);
  auto rate = u.get_number("rate", 1.0, 0, 1e6);
  if (!every) return every.error();
  if (!rate) return rate.error();
  if (*every < 1) return uri_error(u, "every: expected an integer >= 1");
  if (*rate < 0) return uri_error(u, "rate: expected >= 0 (0: as fast as possible)");
  out.scenario = scenario->name;
  // The flight and every sensor, simulated once here for the cameras, the nav streams and the truth.
  auto sim = std::make_shared<SimulatedFlight>();
  sim->scenario = *scenario;
  auto flight = sim::Flight::create(sim->scenario);
  if (!flight) return uri_error(u, flight.error().message);
  sim->flight = std::make_unique<sim::Flight>(std::move(*flight));
  sim->logs = sim::simulate_sensors(sim->scenario, *sim->flight);
  out.sim = sim;
  out.sim_clock = std::make_shared<sim::SimClock>(scenario->start_gps_ns, *rate);
  // Both cameras stamp the simulation's device clocks, which differ by their configured offsets.
  const auto& offs = scenario->sensors.cameras.clock_offset_ns;
  const std::int64_t skew = offs.size() >= 2 ? std::abs(offs[1] - offs[0]) : 0;
  out.options.pairing.tolerance_ns = skew + static_cast<std::int64_t>(0.25e9 / scenario->sensors.cameras.fps);
  out.options.lossless = *rate == 0;
  out.sources.push_back(std::make_unique<SimSource>(u.text, out.sim, static_cast<int>(*every), out.sim_clock,
                                                    boom == "physical"));
  return out;
}

}  // namespace augrig::pipeline
