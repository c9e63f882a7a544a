// bench_h264_client: one H.264 client of a running live view, for the live budget (issue 35 §1:
// two GigE cameras, window, recording and one H.264 client). Connects to augrig's Foxglove server
// (retrying until it is up), subscribes to both augmented views' H.264 topics and reads for
// --seconds, as a ground station would (it does not decode: a real client runs elsewhere). Prints
// units, keyframes, Mbit/s of both views, the largest gap between units and the receive rate.
//   build/bench_h264_client PORT [--seconds S] [--topics T1,T2]
// Run it beside bench_live, e.g.
//   build/bench_live --gige --display --duration 120 --extra "--serve 127.0.0.1:8765" &
//   build/bench_h264_client 8765 --seconds 110
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/support/ws_test_client.hpp"

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Whether an Annex B unit holds an IDR slice (NAL type 5).
bool has_idr(const std::string& d, std::size_t from) {
  for (std::size_t i = from; i + 3 < d.size(); ++i)
    if (d[i] == 0 && d[i + 1] == 0 && d[i + 2] == 1 && (static_cast<unsigned char>(d[i + 3]) & 0x1f) == 5)
      return true;
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_h264_client PORT [--seconds S] [--topics T1,T2]\n");
    return 2;
  }
  const int port = std::atoi(argv[1]);
  double seconds = 60;
  std::vector<std::string> topics = {"/left/image_augmented/h264", "/right/image_augmented/h264"};
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--seconds") {
      seconds = std::atof(argv[i + 1]);
    } else if (a == "--topics") {
      topics.clear();
      std::istringstream in(argv[i + 1]);
      for (std::string t; std::getline(in, t, ',');) topics.push_back(t);
    }
  }
  // Connect, retrying while augrig starts (up to a minute).
  std::unique_ptr<augrig::test::TestWsClient> ws;
  json advertise;
  const auto start = Clock::now();
  while (seconds_since(start) < 60) {
    ws = std::make_unique<augrig::test::TestWsClient>(port);
    if (ws->connected() && ws->handshake("foxglove.websocket.v1").rfind("HTTP/1.1 101", 0) == 0) {
      auto info = ws->read_frame(), adv = ws->read_frame();
      if (info && adv) {
        advertise = json::parse(adv->payload, nullptr, false);
        break;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  if (!advertise.is_object())
    return std::fprintf(stderr, "bench_h264_client: no live view on port %d\n", port), 1;
  json subs = json::array();
  std::uint32_t id = 1;
  for (const json& c : advertise["channels"])
    if (std::find(topics.begin(), topics.end(), c["topic"].get<std::string>()) != topics.end())
      subs.push_back({{"id", id++}, {"channelId", c["id"]}});
  if (subs.size() != topics.size())
    return std::fprintf(stderr, "bench_h264_client: topics not advertised\n"), 1;
  ws->send_text(json{{"op", "subscribe"}, {"subscriptions", subs}}.dump());
  std::map<std::uint32_t, std::uint64_t> units, keys;
  std::uint64_t bytes = 0;
  double largest_gap_s = 0;
  const auto t0 = Clock::now();
  auto last = t0;
  std::fprintf(stderr, "bench_h264_client: subscribed to %zu topics on port %d\n", topics.size(), port);
  while (seconds_since(t0) < seconds) {
    auto f = ws->read_frame(1000);
    if (!f) {
      if (ws->ended()) break;
      continue;
    }
    if (f->opcode != 2 || f->payload.size() < 13) continue;
    std::uint32_t sub = 0;
    for (int b = 0; b < 4; ++b)
      sub |= std::uint32_t{static_cast<unsigned char>(f->payload[1 + b])} << (8 * b);
    ++units[sub];
    keys[sub] += has_idr(f->payload, 13) ? 1 : 0;
    bytes += f->payload.size() - 13;
    const auto now = Clock::now();
    if (units.size() == topics.size())
      largest_gap_s = std::max(largest_gap_s, std::chrono::duration<double>(now - last).count());
    last = now;
  }
  const double s = seconds_since(t0);
  std::printf("bench_h264_client: %.1f s", s);
  for (const auto& [sub, n] : units)
    std::printf(", topic %u: %llu units (%.1f/s), %llu keyframes", sub, static_cast<unsigned long long>(n),
                n / s, static_cast<unsigned long long>(keys[sub]));
  std::printf("; both %.2f Mbit/s; largest gap between units %.0f ms\n", bytes * 8 / s / 1e6,
              1000 * largest_gap_s);
  return 0;
}
