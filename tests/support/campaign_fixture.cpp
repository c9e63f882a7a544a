#include "tests/support/campaign_fixture.hpp"

#include <algorithm>
#include <fstream>
#include <sstream>

#include "tests/support/test_support.hpp"

namespace augrig::test {

namespace fs = std::filesystem;

std::vector<std::string> lines_of(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> v;
  std::string l;
  while (std::getline(in, l)) v.push_back(l);
  return v;
}

std::vector<std::string> without_time_columns(const std::vector<std::string>& rows) {
  if (rows.empty()) return rows;
  auto cells = [](const std::string& s) {
    std::vector<std::string> c;
    std::stringstream ss(s);
    std::string x;
    while (std::getline(ss, x, ',')) c.push_back(x);
    if (!s.empty() && s.back() == ',') c.emplace_back();
    return c;
  };
  const auto head = cells(rows[0]);
  std::vector<std::string> out;
  for (const auto& r : rows) {
    const auto c = cells(r);
    std::string k;
    for (std::size_t i = 0; i < c.size() && i < head.size(); ++i)
      if (head[i].size() < 3 || head[i].substr(head[i].size() - 3) != "_ms") k += c[i] + ",";
    out.push_back(k);
  }
  return out;
}

void CampaignFlights::SetUp() {
  std::string why;
  rec_a = sim_recording("campaign/flight_a.yaml", 3, "campaign_a", &why);
  ASSERT_FALSE(rec_a.empty()) << why;
  rec_b = sim_recording("campaign/flight_b.yaml", 3, "campaign_b", &why);
  ASSERT_FALSE(rec_b.empty()) << why;
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  dir = output_dir(std::string(info->test_suite_name()) + "_" + info->name());
  std::ofstream(dir / "boom.csv") << "t_s,elevation_deg,azimuth_deg,extension_m\n0,22,-10,0.5\n4,38,12,5\n";
}

void CampaignFlights::expect_equals_unsharded(const fs::path& report, const std::string& f,
                                              const std::string& eval_flags, bool stats) {
  SCOPED_TRACE("flight " + f);
  const std::string rec = f == "a" ? rec_a : rec_b;
  const fs::path u = dir / ("unsharded_" + f);
  std::string log;
  // --allow-damaged and --look plain as the tasks run: a damaged frame is left out of both alike.
  ASSERT_EQ(run_augrig("evaluate " + rec + " --boom script:" + (dir / "boom.csv").string() + " " +
                           eval_flags + " --look plain --allow-damaged --no-plot --out " + (u / "eval").string(),
                       &log),
            0)
      << log;
  if (stats) {
    ASSERT_EQ(run_augrig("replay " + rec + " --fast --headless --every 1000000 --allow-damaged --out " +
                             (u / "stats").string(),
                         &log),
              0)
        << log;
    EXPECT_EQ(lines_of(report / "stats" / f / "stats.csv"), lines_of(u / "stats" / "stats.csv"));
  }
  const fs::path e = report / "eval" / f;
  EXPECT_EQ(lines_of(e / "stats.csv"), lines_of(u / "eval" / "stats.csv"));
  EXPECT_EQ(lines_of(e / "evaluation.csv"), lines_of(u / "eval" / "evaluation.csv"));
  EXPECT_EQ(without_time_columns(lines_of(e / "evaluation_sums.csv")),
            without_time_columns(lines_of(u / "eval" / "evaluation_sums.csv")));
  // The table from the re-added sums is the unsharded run's, but for its title line.
  auto merged = lines_of(e / "evaluation.txt"), whole = lines_of(u / "eval" / "evaluation.txt");
  ASSERT_GT(merged.size(), 5u);
  ASSERT_EQ(merged.size(), whole.size());
  EXPECT_TRUE(std::equal(merged.begin() + 1, merged.end(), whole.begin() + 1));
}

}  // namespace augrig::test
