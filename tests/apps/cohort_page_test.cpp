// The cohort QC page (OUT/report.html) loaded in a real browser: headless Chromium runs its script and the rendered
// DOM is checked (a row per case, a sort and a status filter applied from the address, the volume outlier marked, a
// thumbnail per finished case).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <regex>
#include <string>
#include <vector>

#include "msk/imaging/json.h"
#include "msk/test/cli.h"
#include "msk/test/files.h"

namespace fs = std::filesystem;
using msk::test::runCli;

namespace {

/// The DOM Chromium renders for `url` after running the page's script ("" if Chromium is not there or fails).
std::string renderedDom(const std::string& url, const std::string& profileDir) {
  const std::string command = "chromium --headless --no-sandbox --disable-gpu --user-data-dir='" + profileDir +
                              "' --dump-dom '" + url + "' 2>/dev/null";
  std::string out;
  if (FILE* p = ::popen(command.c_str(), "r")) {
    char buffer[65536];
    size_t n;
    while ((n = std::fread(buffer, 1, sizeof buffer, p)) > 0) out.append(buffer, n);
    if (::pclose(p) != 0) return "";
  }
  return out;
}

/// The table's rows as rendered: (case name, hidden?) in document order.
std::vector<std::pair<std::string, bool>> rows(const std::string& dom) {
  std::vector<std::pair<std::string, bool>> out;
  const std::regex row(R"(<tr class="[^"]*" data-status="[^"]*"( hidden="")?><td class="text">([^<]*)</td>)");
  for (auto it = std::sregex_iterator(dom.begin(), dom.end(), row); it != std::sregex_iterator(); ++it)
    out.emplace_back((*it)[2].str(), (*it)[1].matched);
  return out;
}

}  // namespace

TEST(CohortPage, SortsFiltersAndMarksOutliersInABrowser) {
  if (std::system("command -v chromium >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "chromium is not installed (scripts/install-deps.sh installs it)";
  msk::test::ScratchDir dir;
  const std::string sample = msk::test::bundledSample(), cases = dir.file("cases"), out = dir.file("out");
  for (const std::string c : {"p01", "p02", "p03", "p04", "p05"}) {
    fs::create_directories(cases + "/" + c);
    fs::create_symlink(sample + "image.nii.gz", cases + "/" + c + "/image.nii.gz");
  }
  fs::create_directories(cases + "/p06");
  const std::string image = msk::test::readBytes(sample + "image.nii.gz");
  msk::test::writeBytes(cases + "/p06/image.nii.gz", image.substr(0, image.size() / 3));
  const std::string scene = dir.file("scene.json");
  msk::test::writeBytes(
      scene, "{\"objects\": [{\"name\": \"femur\", \"label\": 1, \"kind\": \"bone\", \"template\": \"" + sample +
                 "template_femur.vtk\"}]}");
  auto r = runCli({"batch", "--cases", cases, "--scene", scene, "--out", out, "--jobs", "2", "--", "--quality", "fast",
                   "--threads", "1"});
  ASSERT_EQ(r.exitCode, 1) << r.err;  // p06 fails
  ASSERT_TRUE(fs::exists(out + "/report.html"));
  ASSERT_TRUE(fs::exists(out + "/p01/qc/mosaic.png"));

  // p05's femur made half as large again as the others' (as a bad segmentation would be), gathered by collect.
  msk::Json report = msk::readJsonFile(out + "/p05/report.json");
  report["objects"][0]["volume_mm3"] = 1.5 * report["objects"][0]["volume_mm3"].get<double>();
  msk::writeJsonFile(out + "/p05/report.json", report);
  r = runCli({"collect", "--cases", cases, "--scene", scene, "--out", out});
  ASSERT_EQ(r.exitCode, 0) << r.err;

  const std::string page = "file://" + out + "/report.html";
  const std::string sorted = renderedDom(page + "#sort=case&dir=desc", dir.file("chromium"));
  ASSERT_FALSE(sorted.empty()) << "chromium rendered nothing";
  const auto byName = rows(sorted);
  ASSERT_EQ(byName.size(), 6u) << sorted.substr(0, 2000);
  const std::vector<std::string> expected = {"p06", "p05", "p04", "p03", "p02", "p01"};
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(byName[i].first, expected[i]) << "row " << i << " after sorting by case, descending";
    EXPECT_FALSE(byName[i].second);
  }
  EXPECT_NE(sorted.find(R"(data-key="case" data-type="text" aria-sort="descending")"), std::string::npos);
  // The outlier's cell and the thumbnails (five finished cases; none for the failed one).
  EXPECT_TRUE(std::regex_search(sorted, std::regex(R"(class="outlier" title="[0-9.]+ robust SD)")));
  size_t thumbs = 0;
  for (size_t at = sorted.find("data:image/jpeg;base64,"); at != std::string::npos;
       at = sorted.find("data:image/jpeg;base64,", at + 1))
    ++thumbs;
  EXPECT_EQ(thumbs, 5u);
  EXPECT_NE(sorted.find(R"(href="p01/qc/mosaic.png")"), std::string::npos);

  const auto failedOnly = rows(renderedDom(page + "#status=failed&sort=seconds", dir.file("chromium")));
  ASSERT_EQ(failedOnly.size(), 6u);
  for (const auto& [name, hidden] : failedOnly)
    EXPECT_EQ(hidden, name != "p06") << name << " (only failed cases shown)";
}
