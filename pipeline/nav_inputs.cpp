#include "pipeline/nav_inputs.hpp"

#include "core/thread_name.hpp"
#include "nav/imu_stream.hpp"
#include "recorder/nav_inputs.hpp"

namespace augrig::pipeline {

Expected<std::vector<std::pair<std::string, std::string>>> parse_named_list(const std::string& spec,
                                                                            const std::string& what) {
  std::vector<std::pair<std::string, std::string>> items;
  std::size_t pos = 0;
  while (pos <= spec.size()) {
    const std::size_t comma = std::min(spec.find(',', pos), spec.size());
    const std::string item = spec.substr(pos, comma - pos);
    pos = comma + 1;
    if (item.empty()) continue;
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0) return make_error(what, ", got '", item, "'");
    items.emplace_back(item.substr(0, eq), item.substr(eq + 1));
  }
  return items;
}

Status NavInputs::open(const std::vector<std::pair<std::string, std::string>>& items, recorder::Recorder* rec,
                       LiveNav* live_nav) {
  for (const auto& [stream, uri] : items) {
    Input in;
    in.stream = stream;
    in.aircraft = aircraft_of_stream(stream);
    auto input = nav::open_nav_input(uri);
    if (!input) return input.error();
    in.input = std::move(*input);
    inputs_.push_back(std::move(in));
  }
  for (Input& in : inputs_) {
    if (rec) {
      // Every unit recorded exactly as received, stamped with its host arrival time and, where the
      // data says it, its sensor time (one stamper per input: an NMEA stream's date is its own).
      auto stamper = std::make_shared<recorder::NavInputStamper>();
      in.input->set_raw_tap(
          [rec, stream = in.stream, stamper](std::string_view data, TimestampNs arrival_ns, bool binary) {
            recorder::NavInputRecord r;
            r.stream = stream;
            r.arrival_ns = arrival_ns;
            r.data = std::string(data);
            r.binary = binary;
            stamper->stamp(r);
            rec->push(std::move(r));
          });
    }
    in.thread = std::thread([this, &in, live_nav] {
      set_thread_name("augrig-nav");
      nav::NavEvent e;
      while (!stop_) {
        auto r = in.input->read(e, std::chrono::milliseconds(100));
        if (!r) {
          in.error = r.error().message;
          return;
        }
        if (*r == nav::NavReadStatus::kEnd) return;
        if (*r != nav::NavReadStatus::kEvent) continue;
        (e.is_imu() ? in.imu : e.is_baseline() ? in.baselines : in.fixes)++;
        if (live_nav && in.aircraft) live_nav->add(*in.aircraft, e);
      }
    });
  }
  return {};
}

std::uint16_t NavInputs::port(const std::string& stream) const {
  for (const Input& in : inputs_)
    if (in.stream == stream) return in.input->udp_port();
  return 0;
}

void NavInputs::stop() {
  stop_ = true;
  for (Input& in : inputs_)
    if (in.thread.joinable()) in.thread.join();
}

void NavInputs::summary(std::ostream& out) const {
  for (const Input& in : inputs_) {
    const nav::NavInputStats st = in.input->stats();
    out << "nav " << in.stream << " (" << in.input->uri() << "): " << in.fixes << " fixes, " << in.imu
        << " IMU samples" << (in.baselines ? ", " + std::to_string(in.baselines) + " moving baselines" : "")
        << "; malformed " << st.malformed << ", oversized " << st.oversized << ", lost " << st.dropped
        << (in.error.empty() ? "" : "; stopped: " + in.error)
        << (st.last_errors.empty() ? "" : "; last problem: " + st.last_errors.back()) << "\n";
  }
}

void NavInputs::ledger(recorder::Recorder& rec) const {
  for (const Input& in : inputs_) {
    const nav::NavInputStats st = in.input->stats();
    const std::uint64_t lost = st.malformed + st.oversized + st.dropped;
    if (lost)
      rec.push(recorder::DropRecord{recorder::DropStage::kTransport, lost, 0, 0,
                                    in.stream + ": malformed, oversized or lost nav input", "nav_input"});
  }
}

}  // namespace augrig::pipeline
