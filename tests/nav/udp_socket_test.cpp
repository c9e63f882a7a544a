// Tests for nav/udp_socket.hpp against the kernel's own UDP: a real sender and receiver on the
// loopback interface, datagrams larger than the maximum, a full receive buffer, bad addresses.
#include "nav/udp_socket.hpp"

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "nav/live_input.hpp"

namespace augrig::nav {
namespace {

using namespace std::chrono_literals;

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

TEST(UdpSocket, ParsesHostPort) {
  auto a = parse_host_port("127.0.0.1:10110", "t: ");
  ASSERT_TRUE(a) << a.error().message;
  EXPECT_EQ(a->host, "127.0.0.1");
  EXPECT_EQ(a->port, 10110);
  auto b = parse_host_port("[::1]:0", "t: ");
  ASSERT_TRUE(b) << b.error().message;
  EXPECT_EQ(b->host, "::1");
  EXPECT_EQ(b->port, 0);
  for (const char* bad :
       {"127.0.0.1", "127.0.0.1:", ":5000", "host:70000", "host:5x", "::1:5000", "[::1]5000", "[::1"}) {
    auto e = parse_host_port(bad, "t: ");
    ASSERT_FALSE(e) << bad;
    EXPECT_EQ(e.error().message.rfind("t: expected HOST:PORT", 0), 0u) << e.error().message;
    EXPECT_TRUE(contains(e.error().message, bad)) << e.error().message;
  }
}

TEST(UdpSocket, DatagramsArriveWithSourceAndMonotonicArrival) {
  auto rx = UdpReceiver::bind("127.0.0.1", 0);
  ASSERT_TRUE(rx) << rx.error().message;
  ASSERT_NE(rx->port(), 0);
  EXPECT_EQ(rx->address(), "127.0.0.1:" + std::to_string(rx->port()));
  EXPECT_GT(rx->receive_buffer_bytes(), 0);
  auto tx = UdpSender::open("127.0.0.1", rx->port());
  ASSERT_TRUE(tx) << tx.error().message;
  EXPECT_EQ(tx->destination(), rx->address());

  UdpDatagram d;
  auto none = rx->receive(d, 0ns);  // nothing yet: no wait, no datagram
  ASSERT_TRUE(none);
  EXPECT_FALSE(*none);

  const TimestampNs before = monotonic_now_ns();
  ASSERT_TRUE(tx->send(std::string_view("hello")));
  const std::vector<std::uint8_t> binary = {0, 1, 2, 255, 0};
  ASSERT_TRUE(tx->send(binary));
  ASSERT_TRUE(tx->send(std::string_view("")));  // an empty datagram is a datagram too
  auto got = rx->receive(d, 2s);
  ASSERT_TRUE(got && *got);
  const TimestampNs after = monotonic_now_ns();
  EXPECT_EQ(std::string(d.bytes.begin(), d.bytes.end()), "hello");
  EXPECT_EQ(d.size, 5u);
  EXPECT_FALSE(d.oversized);
  EXPECT_GE(d.arrival_ns, before);
  EXPECT_LE(d.arrival_ns, after);
  EXPECT_EQ(d.source.rfind("127.0.0.1:", 0), 0u) << d.source;
  const TimestampNs first_arrival = d.arrival_ns;
  got = rx->receive(d, 2s);
  ASSERT_TRUE(got && *got);
  EXPECT_EQ(d.bytes, binary);
  EXPECT_GE(d.arrival_ns, first_arrival);
  got = rx->receive(d, 2s);
  ASSERT_TRUE(got && *got);
  EXPECT_TRUE(d.bytes.empty());
  EXPECT_EQ(d.size, 0u);
  // A timeout returns without a datagram, and not before its time.
  const TimestampNs t0 = monotonic_now_ns();
  got = rx->receive(d, 30ms);
  ASSERT_TRUE(got);
  EXPECT_FALSE(*got);
  EXPECT_GE(monotonic_now_ns() - t0, 30'000'000);
}

TEST(UdpSocket, OversizedDatagramsAreDetectedNotTruncated) {
  UdpReceiverOptions o;
  o.max_datagram_bytes = 100;
  auto rx = UdpReceiver::bind("127.0.0.1", 0, o);
  ASSERT_TRUE(rx) << rx.error().message;
  auto tx = UdpSender::open("127.0.0.1", rx->port());
  ASSERT_TRUE(tx) << tx.error().message;
  ASSERT_TRUE(tx->send(std::string(100, 'a')));    // exactly the maximum: kept
  ASSERT_TRUE(tx->send(std::string(101, 'b')));    // one more: oversized
  ASSERT_TRUE(tx->send(std::string(60000, 'c')));  // far more
  ASSERT_TRUE(tx->send(std::string(7, 'd')));
  UdpDatagram d;
  ASSERT_TRUE(*rx->receive(d, 2s));
  EXPECT_FALSE(d.oversized);
  EXPECT_EQ(d.bytes, std::vector<std::uint8_t>(100, 'a'));
  ASSERT_TRUE(*rx->receive(d, 2s));
  EXPECT_TRUE(d.oversized);
  EXPECT_EQ(d.size, 101u);
  EXPECT_TRUE(d.bytes.empty());
  ASSERT_TRUE(*rx->receive(d, 2s));
  EXPECT_TRUE(d.oversized);
  EXPECT_EQ(d.size, 60000u);
  ASSERT_TRUE(*rx->receive(d, 2s));  // and the next one is whole
  EXPECT_FALSE(d.oversized);
  EXPECT_EQ(d.bytes, std::vector<std::uint8_t>(7, 'd'));
}

TEST(UdpSocket, KernelDropsForAFullBufferAreCounted) {
  UdpReceiverOptions o;
  o.receive_buffer_bytes = 4096;  // the kernel raises it to its minimum: still small
  auto rx = UdpReceiver::bind("127.0.0.1", 0, o);
  ASSERT_TRUE(rx) << rx.error().message;
  auto tx = UdpSender::open("127.0.0.1", rx->port());
  ASSERT_TRUE(tx) << tx.error().message;
  const int sent = 3000;
  for (int i = 0; i < sent; ++i) ASSERT_TRUE(tx->send(std::string(1000, 'x')));
  UdpDatagram d;
  int received = 0;
  std::uint64_t dropped = 0;
  while (*rx->receive(d, 100ms)) {
    ++received;
    dropped += d.overflow_drops;
  }
  EXPECT_LT(received, sent);
  // The kernel's count rides on the datagrams queued after the drops: send one more to learn it.
  ASSERT_TRUE(tx->send(std::string_view("marker")));
  ASSERT_TRUE(*rx->receive(d, 2s));
  EXPECT_EQ(d.size, 6u);
  dropped += d.overflow_drops;
  EXPECT_GT(dropped, 0u);
  EXPECT_EQ(static_cast<std::uint64_t>(received) + dropped, static_cast<std::uint64_t>(sent));
  // Counted once: the next datagram brings no new drops.
  ASSERT_TRUE(tx->send(std::string_view("again")));
  ASSERT_TRUE(*rx->receive(d, 2s));
  EXPECT_EQ(d.overflow_drops, 0u);
}

TEST(UdpSocket, Ipv6Loopback) {
  auto rx = UdpReceiver::bind("::1", 0);
  if (!rx && contains(rx.error().message, "resolve")) GTEST_SKIP() << "no IPv6 here: " << rx.error().message;
  ASSERT_TRUE(rx) << rx.error().message;
  EXPECT_EQ(rx->address(), "[::1]:" + std::to_string(rx->port()));
  auto tx = UdpSender::open("::1", rx->port());
  ASSERT_TRUE(tx) << tx.error().message;
  ASSERT_TRUE(tx->send(std::string_view("six")));
  UdpDatagram d;
  ASSERT_TRUE(*rx->receive(d, 2s));
  EXPECT_EQ(d.size, 3u);
  EXPECT_EQ(d.source.rfind("[::1]:", 0), 0u) << d.source;
}

TEST(UdpSocket, BadAddressesAreErrorsThatSayWhy) {
  auto taken = UdpReceiver::bind("127.0.0.1", 0);
  ASSERT_TRUE(taken) << taken.error().message;
  auto again = UdpReceiver::bind("127.0.0.1", taken->port());
  ASSERT_FALSE(again);
  EXPECT_TRUE(contains(again.error().message, "cannot bind")) << again.error().message;
  EXPECT_TRUE(contains(again.error().message, "another socket has this port")) << again.error().message;
  EXPECT_EQ(
      again.error().message.rfind("nav::UdpReceiver::bind(): 127.0.0.1:" + std::to_string(taken->port()), 0),
      0u);

  auto foreign = UdpReceiver::bind("192.0.2.1", 0);  // TEST-NET-1: no interface has it
  ASSERT_FALSE(foreign);
  EXPECT_TRUE(contains(foreign.error().message, "no interface of this host has that address"))
      << foreign.error().message;

  auto junk = UdpReceiver::bind("not an address!", 0);
  ASSERT_FALSE(junk);
  EXPECT_TRUE(contains(junk.error().message, "cannot resolve the address 'not an address!'"))
      << junk.error().message;

  UdpReceiverOptions huge;
  huge.max_datagram_bytes = 70000;
  auto h = UdpReceiver::bind("127.0.0.1", 0, huge);
  ASSERT_FALSE(h);
  EXPECT_TRUE(contains(h.error().message, "max_datagram_bytes must be 1..65507")) << h.error().message;

  auto zero = UdpSender::open("127.0.0.1", 0);
  ASSERT_FALSE(zero);
  EXPECT_TRUE(contains(zero.error().message, "destination port")) << zero.error().message;
  auto bcast = UdpSender::open("255.255.255.255", 9);
  ASSERT_FALSE(bcast);
  EXPECT_TRUE(contains(bcast.error().message, "broadcast")) << bcast.error().message;
}

TEST(UdpSocket, SendingToNobodyIsReportedOnTheNextSend) {
  int port = 0;
  {
    auto rx = UdpReceiver::bind("127.0.0.1", 0);
    ASSERT_TRUE(rx);
    port = rx->port();
  }  // closed: nothing listens there now
  auto tx = UdpSender::open("127.0.0.1", static_cast<std::uint16_t>(port));
  ASSERT_TRUE(tx);
  // The first datagram goes out; the ICMP "port unreachable" it draws fails a later send.
  Status last;
  for (int i = 0; i < 20 && last; ++i) {
    last = tx->send(std::string_view("x"));
    std::this_thread::sleep_for(1ms);
  }
  ASSERT_FALSE(last);
  EXPECT_TRUE(contains(last.error().message, "nothing listens there")) << last.error().message;
}

}  // namespace
}  // namespace augrig::nav
