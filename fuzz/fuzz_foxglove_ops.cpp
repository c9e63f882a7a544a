// The live view's parser of a Foxglove client's ops (net/foxglove_ops.hpp): a selector byte (bit 0:
// a binary message) and the message. Whatever comes: an error says why, an op lists its entries,
// each well-formed or with its problem, and a well-formed entry's numbers are what the JSON held.
#include <cstdlib>
#include <string>

#include "fuzz/fuzz_common.hpp"
#include "net/foxglove_ops.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using augrig::net::ClientOp;
  augrig::fuzz::Input in(data, size);
  const bool binary = in.byte() & 1;
  const std::string text(in.bytes(in.left()));
  const ClientOp op = augrig::net::parse_client_op(binary, text);
  if (op.kind == ClientOp::Kind::kError) {
    if (op.error.empty() || !op.entries.empty()) std::abort();
    return 0;
  }
  if (binary || !op.error.empty()) std::abort();
  for (const ClientOp::Entry& e : op.entries) {
    if (!e.problem.empty() && (e.id != 0 || e.channel != 0)) std::abort();
    if (op.kind == ClientOp::Kind::kUnsubscribe && e.channel != 0) std::abort();
  }
  return 0;
}
