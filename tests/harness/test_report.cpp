// The HTML report folder (crossdyn verify --report DIR): complete and self-contained. The
// committed example (reports/example/, linked from the README) is regenerated into the build
// folder with the same command and both are checked: index.html, one page per scene, every image
// and link they reference exists, nothing is fetched from the network, and the regenerated set
// has the same pages and charts as the committed one.
#include <catch2/catch.hpp>

#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

namespace fs = std::filesystem;

namespace {

// The scenes of reports/example/ (keep in step with reports/README.md).
const char* const kExampleScenes =
    "scenarios/spear1_case1.yaml scenarios/spear1_case2.yaml scenarios/torque_free_asymmetric.yaml";

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Every src="..." and href="..." of a page.
std::vector<std::string> references(const std::string& html) {
  std::vector<std::string> out;
  const std::regex ref(R"re((?:src|href)="([^"]*)")re");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), ref); it != std::sregex_iterator(); ++it)
    out.push_back((*it)[1].str());
  return out;
}

// Checks a report folder; returns the names of its pages and images.
std::set<std::string> check_complete(const fs::path& dir, std::size_t scenes_expected) {
  INFO("report folder " << dir.string());
  REQUIRE(fs::exists(dir / "index.html"));
  REQUIRE(fs::exists(dir / "summary.json"));
  const nlohmann::json summary = nlohmann::json::parse(read_text(dir / "summary.json"));
  REQUIRE(summary["scenes"].size() == scenes_expected);
  std::set<std::string> files{"index.html"};

  const std::string index = read_text(dir / "index.html");
  const std::vector<std::string> index_refs = references(index);
  for (const nlohmann::json& s : summary["scenes"]) {
    const std::string page = s["page"];
    INFO("scene page " << page);
    CHECK(fs::exists(dir / page));
    CHECK(std::find(index_refs.begin(), index_refs.end(), page) != index_refs.end());
    files.insert(page);
    const std::string html = read_text(dir / page);
    CHECK(html.find("</html>") != std::string::npos);  // complete, not truncated
    CHECK(html.find("Checks") != std::string::npos);
    int images = 0;
    for (const std::string& r : references(html)) {
      INFO("reference " << r);
      CHECK(r.find("://") == std::string::npos);  // works offline
      CHECK(r.find("..") == std::string::npos);   // stays inside the folder
      CHECK(fs::exists(dir / r));
      if (r.size() > 4 && r.compare(r.size() - 4, 4, ".png") == 0) {
        ++images;
        files.insert(r);
        CHECK(fs::file_size(dir / r) > 1000);
      }
    }
    // Angular velocity, joints (when the scene has joints), H and E, differences, drift.
    CHECK(images >= 4);
  }
  for (const std::string& r : index_refs) CHECK(r.find("://") == std::string::npos);
  // No temporary file left behind by an atomic write.
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    CHECK(e.path().filename().string().find(".tmp.") == std::string::npos);
  return files;
}

}  // namespace

TEST_CASE("report: the regenerated example folder is complete and matches the committed one") {
  const fs::path out = fs::path(crossdyn::test::binary_dir()) / "test-report-example";
  fs::remove_all(out);
  const auto r = crossdyn::test::run_crossdyn(std::string("verify --quiet ") + kExampleScenes +
                                              " --report '" + out.string() + "' --junit '" +
                                              (out / "junit.xml").string() + "'");
  INFO(r.output);
  REQUIRE((r.status == 0 || r.status == 1));  // 1: some check failed; the report is still made
  CHECK(r.output.find("report: " + out.string() + "/index.html") != std::string::npos);
  const std::set<std::string> fresh = check_complete(out, 3);
  CHECK(fs::exists(out / "junit.xml"));

  const fs::path example = fs::path(crossdyn::test::source_dir()) / "reports" / "example";
  REQUIRE(fs::exists(example));
  const std::set<std::string> committed = check_complete(example, 3);
  CHECK(fresh == committed);
}

TEST_CASE("report: a scene that cannot be read still gets a page and the index") {
  const fs::path out = fs::path(crossdyn::test::binary_dir()) / "test-report-bad";
  fs::remove_all(out);
  fs::create_directories(out);
  {
    std::ofstream bad(out / "broken.yaml");
    bad << "name: broken\nbodies: [1, 2\n";
  }
  const auto r = crossdyn::test::run_crossdyn("verify --quiet '" + (out / "broken.yaml").string() +
                                              "' --report '" + (out / "report").string() + "'");
  INFO(r.output);
  CHECK(r.status == 2);
  CHECK(r.output.find("broken.yaml") != std::string::npos);
  REQUIRE(fs::exists(out / "report" / "index.html"));
  REQUIRE(fs::exists(out / "report" / "broken.html"));
  CHECK(read_text(out / "report" / "broken.html").find("Bad input") != std::string::npos);
}
