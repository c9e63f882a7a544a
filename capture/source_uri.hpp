// Source URIs, Pangolin style: what names a frame source in a rig file and on the command line.
//
//   aravis://<id|serial|ip>[?format=BayerRG8&fps=30&exposure_us=5000&gain=0&roi=X,Y,W,H
//                           &trigger=free|software|Line0&ptp=1&packet_size=8000&buffers=16]
//   v4l2:///dev/videoN[?format=YUYV&width=1280&height=960&fps=30&buffers=4&exposure=..&gain=..]
//   sim://<scenario name or file>[?every=K&rate=1]
//   replay://<recording dir>[?rate=1|fast&loop=1]
//   stereo:[tolerance_us=2000,mode=timestamp|trigger_id,clock=shared|separate]//{LEFT URI}{RIGHT URI}
//
// parse_source_uri() only checks the syntax and splits the parts; what each scheme accepts is
// checked where the source is opened, against SourceUri::take() so unknown parameters are errors.
#pragma once

#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "core/expected.hpp"

namespace augrig {

struct SourceUri {
  std::string text;                           // as given
  std::string scheme;                         // "aravis", "v4l2", "sim", "replay", "stereo"
  std::string target;                         // what follows "scheme://" up to '?' (device, path, scenario)
  std::map<std::string, std::string> params;  // query (or stereo's [..]) parameters
  std::vector<SourceUri> children;            // stereo: {left, right}

  bool has(const std::string& key) const { return params.count(key) != 0; }
  // The value of `key`; `fallback` when absent.
  std::string get(const std::string& key, const std::string& fallback = "") const;
  // A finite number (nan, inf and overflowing text are errors) in [lo, hi]; `fallback` when
  // absent. The error names the URI, the key, the range and the text.
  Expected<double> get_number(const std::string& key, double fallback, double lo = -1e15,
                              double hi = 1e15) const;
  Expected<long long> get_integer(const std::string& key, long long fallback, long long lo = -(1LL << 53),
                                  long long hi = 1LL << 53) const;
  // Error naming the URI and every parameter not in `known`.
  Status check_known(std::initializer_list<std::string_view> known) const;
};

// Splits a URI; errors say what was expected: "source URI 'xyz': expected scheme://...".
Expected<SourceUri> parse_source_uri(std::string_view text);

}  // namespace augrig
