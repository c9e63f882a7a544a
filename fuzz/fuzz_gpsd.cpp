// GpsdReportMerger (nav/gpsd_input.hpp): gpsd JSON reports, one per line, unpacked with libgps and
// merged into fixes, with quiet-time polls between them as the live input does.
#include <string_view>

#include "nav/gpsd_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view text(reinterpret_cast<const char*>(data), size);
  augrig::nav::GpsdOptions options;
  augrig::nav::GpsdReportMerger merger("fuzz", options);
  augrig::TimestampNs now = 1'000'000'000;
  augrig::nav::NavEvent event;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    merger.push_report(text.substr(0, nl), now);
    text = nl == std::string_view::npos ? std::string_view() : text.substr(nl + 1);
    now += 7'000'000;
    merger.poll_quiet(now);
    while (merger.pop(event)) {
    }
  }
  merger.flush();
  while (merger.pop(event)) {
  }
  return 0;
}
