// parse_source_uri (capture/source_uri.hpp): the source URIs of the command line, and the typed
// parameter getters on what parses.
#include <string_view>

#include "capture/source_uri.hpp"

namespace {
void visit(const augrig::SourceUri& uri) {
  for (const auto& [key, value] : uri.params) {
    (void)uri.get_number(key, 0.0);
    (void)uri.get_integer(key, 0);
  }
  (void)uri.check_known({"fps", "format", "width", "height"});
  for (const auto& child : uri.children) visit(child);
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto uri = augrig::parse_source_uri(std::string_view(reinterpret_cast<const char*>(data), size));
  if (uri) visit(*uri);
  return 0;
}
