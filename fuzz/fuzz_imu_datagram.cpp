// IMU datagrams (nav/imu_stream.hpp): decode_imu_datagram and the stream decoder behind the UDP
// input. Input: datagrams, each a 2-byte little-endian length and its bytes. A random CRC almost
// never matches, so when the length's top bit is set the target writes the right CRC over the
// last 4 bytes: the checks after the CRC get fuzzed too.
#include <vector>

#include "fuzz/fuzz_common.hpp"
#include "nav/imu_stream.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  augrig::fuzz::Input input(data, size);
  augrig::nav::ImuStreamOptions options;
  options.restart_after_samples = 1 + input.byte() * 8u;
  augrig::nav::ImuStreamDecoder decoder("fuzz", options);
  augrig::TimestampNs arrival = 1'000'000'000;
  while (input.left() > 0) {
    const std::uint16_t head = input.value<std::uint16_t>();
    const std::string_view piece = input.bytes(head & 0x7fff);
    std::vector<std::uint8_t> d(piece.begin(), piece.end());
    if ((head & 0x8000) && d.size() >= augrig::nav::kImuCrcBytes) {
      const std::size_t n = d.size() - augrig::nav::kImuCrcBytes;
      const std::uint32_t crc = augrig::nav::crc32_ieee(std::span<const std::uint8_t>(d.data(), n));
      for (int k = 0; k < 4; ++k) d[n + k] = static_cast<std::uint8_t>(crc >> (8 * k));
    }
    (void)augrig::nav::decode_imu_datagram(d);
    decoder.push(d, arrival, "127.0.0.1:9");
    arrival += 5'000'000;
    augrig::nav::NavEvent event;
    while (decoder.pop(event)) {
    }
  }
  return 0;
}
