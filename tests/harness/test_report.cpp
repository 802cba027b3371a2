// The HTML report folder (crossdyn verify --report DIR): complete and self-contained. The
// committed example (reports/example/, linked from the README) is regenerated into the build
// folder with the same command and both are checked: index.html, one page per scene, every image
// and link they reference exists (the runs' CSV files only in the regenerated one: they are not
// committed), nothing is fetched from the network, every scene page shows the scene's picture,
// and the regenerated set has the same pages and charts as the committed one. Two verify runs
// writing one report folder at once leave one whole report, never a mixture; a folder that is not
// a report is never replaced.
#include <catch2/catch.hpp>

#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

namespace fs = std::filesystem;

namespace {

// The scenes of reports/example/ (keep in step with reports/README.md).
const char* const kExampleScenes =
    "scenarios/spear1_case1.yaml scenarios/spear1_case2.yaml scenarios/torque_free_asymmetric.yaml "
    "scenarios/pointing_flex.yaml";

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

// The visible text of a page: tags (and their attributes, such as tooltips) removed, the end of a
// cell, item or paragraph as a space, white space collapsed.
std::string visible_text(const std::string& html) {
  std::string t = std::regex_replace(html, std::regex("</(td|th|li|p|h1|h2|tr|div|small|pre)>"), " ");
  t = std::regex_replace(t, std::regex("<[^>]*>"), "");
  return std::regex_replace(t, std::regex("\\s+"), " ");
}

// Checks a report folder; returns the names of its pages and images. `csv_committed`: the runs'
// CSV files are there (a fresh report), else links to data/ may point at nothing (the committed
// example leaves them out).
std::set<std::string> check_complete(const fs::path& dir, std::size_t scenes_expected, bool csv_present = true) {
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
    const std::string id = s["id"];
    INFO("scene page " << page);
    CHECK(fs::exists(dir / page));
    CHECK(std::find(index_refs.begin(), index_refs.end(), page) != index_refs.end());
    files.insert(page);
    const std::string html = read_text(dir / page);
    CHECK(html.find("</html>") != std::string::npos);  // complete, not truncated
    CHECK(html.find("<script") == std::string::npos);   // readable without JavaScript
    CHECK(html.find("Checks") != std::string::npos);
    int images = 0, csv_links = 0;
    std::set<std::string> refs;
    for (const std::string& r : references(html)) {
      INFO("reference " << r);
      refs.insert(r);
      CHECK(r.find("://") == std::string::npos);  // works offline
      CHECK(r.find("..") == std::string::npos);   // stays inside the folder
      const bool csv = r.size() > 4 && r.compare(r.size() - 4, 4, ".csv") == 0;
      if (csv) {
        ++csv_links;
        CHECK(r.rfind("data/" + id + "/", 0) == 0);
      }
      if (csv_present || !csv) CHECK(fs::exists(dir / r));
      if (r.size() > 4 && r.compare(r.size() - 4, 4, ".png") == 0) {
        ++images;
        files.insert(r);
        CHECK(fs::file_size(dir / r) > 1000);
        CHECK(fs::file_size(dir / r) < 400000);  // the committed example stays small
      }
    }
    // The scene drawn at t = 0 and later, angular velocity, joints (when the scene has joints),
    // H and E, differences, drift; a link to every run's CSV.
    CHECK(refs.count(id + "-scene.png") == 1);
    CHECK(refs.count(id + "-motion.png") == 1);
    CHECK(images >= 6);
    CHECK(csv_links == static_cast<int>(s["runs"].size()));
  }
  for (const std::string& r : index_refs) CHECK(r.find("://") == std::string::npos);
  // No temporary file left behind by an atomic write.
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    CHECK(e.path().filename().string().find(".tmp.") == std::string::npos);
  return files;
}

// The pages and data folders of a report folder, and the scenes its summary names.
struct ReportContents {
  std::set<std::string> pages, data_dirs, summary_pages, summary_ids;
};
ReportContents contents(const fs::path& dir) {
  ReportContents c;
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".html") c.pages.insert(e.path().filename().string());
  if (fs::exists(dir / "data"))
    for (const fs::directory_entry& e : fs::directory_iterator(dir / "data")) c.data_dirs.insert(e.path().filename().string());
  const nlohmann::json summary = nlohmann::json::parse(read_text(dir / "summary.json"));
  c.summary_pages.insert("index.html");
  for (const nlohmann::json& s : summary["scenes"]) {
    c.summary_pages.insert(s["page"].get<std::string>());
    c.summary_ids.insert(s["id"].get<std::string>());
  }
  return c;
}

// Folders next to `dir` left by a report that was being written.
std::vector<std::string> partial_folders(const fs::path& dir) {
  std::vector<std::string> out;
  for (const fs::directory_entry& e : fs::directory_iterator(dir.parent_path()))
    if (e.path().filename().string().rfind(dir.filename().string() + ".partial-", 0) == 0)
      out.push_back(e.path().string());
  return out;
}

}  // namespace

TEST_CASE("report: the regenerated example folder is complete and matches the committed one") {
  const fs::path out = fs::path(crossdyn::test::binary_dir()) / "test-report-example";
  fs::remove_all(out);
  // The JUnit file beside the folder: an output inside --report is refused (the report replaces
  // its folder as a whole).
  const fs::path junit = out.string() + "-junit.xml";
  fs::remove(junit);
  const auto r = crossdyn::test::run_crossdyn(std::string("verify --quiet ") + kExampleScenes +
                                              " --report '" + out.string() + "' --junit '" +
                                              junit.string() + "'");
  INFO(r.output);
  REQUIRE((r.status == 0 || r.status == 1));  // 1: some check failed; the report is still made
  CHECK(r.output.find("report: " + out.string() + "/index.html") != std::string::npos);
  const std::set<std::string> fresh = check_complete(out, 4);
  CHECK(fs::exists(junit));

  const fs::path example = fs::path(crossdyn::test::source_dir()) / "reports" / "example";
  REQUIRE(fs::exists(example));
  const std::set<std::string> committed = check_complete(example, 4, /*csv_present=*/false);
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

TEST_CASE("report: the index says how many scenes passed, failed and could not be read, and names what failed") {
  // spear1_case1 with a deliberately wrong engine (kane with 0.1 % more inertia) fails; the
  // broken scene cannot be read.
  const fs::path out = fs::path(crossdyn::test::binary_dir()) / "test-report-headline";
  fs::remove_all(out);
  fs::create_directories(out);
  {
    std::ofstream bad(out / "broken.yaml");
    bad << "name: broken\nbodies: [1, 2\n";
  }
  const auto r = crossdyn::test::run_crossdyn(
      "verify --quiet scenarios/spear1_case1.yaml '" + (out / "broken.yaml").string() +
      "' --engines kane --test-inertia-scale kane=1.001 --report '" + (out / "report").string() + "'");
  INFO(r.output);
  REQUIRE(fs::exists(out / "report" / "index.html"));
  const std::string index = visible_text(read_text(out / "report" / "index.html"));
  INFO(index);
  CHECK(index.find("FAIL: 2 scenes: 0 passed, 1 failed (a check did not pass), 1 could not be read.") !=
        std::string::npos);
  // The normalised numbers are explained on the page, and the failing checks are named in it.
  CHECK(index.find("error / (atol + rtol * scale)") != std::string::npos);
  CHECK(index.find("1 or less passes") != std::string::npos);
  CHECK(index.find("What failed") != std::string::npos);
  CHECK(index.find("spear1_case1: main.wx, kane*1.001 vs kane: max error") != std::string::npos);
  CHECK(index.find("broken: could not be read: ") != std::string::npos);
  // No column for what no scene has (no flexible bodies: no modal coordinates).
  CHECK(index.find("modal") == std::string::npos);
  const std::string page = visible_text(read_text(out / "report" / "spear1_case1.html"));
  CHECK(page.find("Failed checks") != std::string::npos);
  CHECK(page.find("main.wx, kane*1.001 vs kane: max error") != std::string::npos);
  CHECK(page.find("flexible modes") == std::string::npos);
}

TEST_CASE("report: two verify runs writing one report folder at once leave one whole report") {
  // Each run writes a different scene; with both writing into the folder in place, the folder
  // would end with both scenes' pages and one index. Run the pair a few times.
  const fs::path out = fs::path(crossdyn::test::binary_dir()) / "test-report-concurrent" / "report";
  fs::remove_all(out.parent_path());
  fs::create_directories(out.parent_path());
  const std::string a = "verify --quiet scenarios/torque_free_asymmetric.yaml --report '" + out.string() + "'";
  const std::string b = "verify --quiet scenarios/spear1_case1.yaml --report '" + out.string() + "'";
  for (int round = 0; round < 2; ++round) {
    INFO("round " << round);
    crossdyn::test::ProgramResult ra, rb;
    std::thread ta([&] { ra = crossdyn::test::run_crossdyn(a); });
    std::thread tb([&] { rb = crossdyn::test::run_crossdyn(b); });
    ta.join();
    tb.join();
    INFO(ra.output << rb.output);
    CHECK(ra.status == 0);
    CHECK(rb.status == 0);
    const ReportContents c = contents(out);
    CHECK(c.summary_ids.size() == 1);
    CHECK(c.pages == c.summary_pages);    // the pages of one run only, and all of them
    CHECK(c.data_dirs == c.summary_ids);  // its data only
    check_complete(out, 1);
    CHECK(partial_folders(out).empty());
  }
}

TEST_CASE("report: a folder that is not a report is never replaced: other files in a report folder are kept") {
  const fs::path base = fs::path(crossdyn::test::binary_dir()) / "test-report-folders";
  fs::remove_all(base);
  fs::create_directories(base / "mine");
  {
    std::ofstream(base / "mine" / "notes.html") << "<p>my notes</p>\n";
  }
  auto r = crossdyn::test::run_crossdyn("verify --quiet scenarios/torque_free_asymmetric.yaml --report '" +
                                        (base / "mine").string() + "'");
  INFO(r.output);
  CHECK(r.output.find("--report: '" + (base / "mine").string() +
                      "' is not a crossdyn report folder (it has no summary.json written by crossdyn) "
                      "but holds 'notes.html', which the report would replace") != std::string::npos);
  CHECK(read_text(base / "mine" / "notes.html") == "<p>my notes</p>\n");
  CHECK_FALSE(fs::exists(base / "mine" / "index.html"));

  // A file, not a folder.
  { std::ofstream(base / "file") << "x\n"; }
  r = crossdyn::test::run_crossdyn("verify --quiet scenarios/torque_free_asymmetric.yaml --report '" +
                                   (base / "file").string() + "'");
  CHECK(r.output.find("--report: '" + (base / "file").string() + "' is a file, not a folder") != std::string::npos);
  CHECK(read_text(base / "file") == "x\n");

  // A folder holding the scene: replacing it would delete the scene.
  fs::create_directories(base / "scenes");
  fs::copy_file(fs::path(crossdyn::test::source_dir()) / "scenarios" / "torque_free_asymmetric.yaml",
                base / "scenes" / "s.yaml");
  r = crossdyn::test::run_crossdyn("verify --quiet '" + (base / "scenes" / "s.yaml").string() + "' --report '" +
                                   (base / "scenes").string() + "'");
  CHECK(r.output.find("' holds the scene file '") != std::string::npos);
  CHECK(fs::exists(base / "scenes" / "s.yaml"));

  // An output of the same command inside the folder is refused before the work (the report
  // replaces its folder as a whole; issue 23 class 2), and nothing is written.
  const fs::path rep = base / "report";
  r = crossdyn::test::run_crossdyn("verify --quiet scenarios/torque_free_asymmetric.yaml --report '" + rep.string() +
                                   "' --junit '" + (rep / "junit.xml").string() + "'");
  CHECK(r.status == 2);
  CHECK(r.output.find("is inside --report") != std::string::npos);
  CHECK_FALSE(fs::exists(rep));
  // A report folder with files the report did not write (a JUnit file and notes put there
  // later): kept, while the report's own pages are replaced.
  r = crossdyn::test::run_crossdyn("verify --quiet scenarios/torque_free_asymmetric.yaml --report '" + rep.string() + "'");
  INFO(r.output);
  REQUIRE(r.status == 0);
  { std::ofstream(rep / "junit.xml") << "<testsuites/>\n"; }
  { std::ofstream(rep / "notes.txt") << "keep me\n"; }
  r = crossdyn::test::run_crossdyn("verify --quiet scenarios/spear1_case1.yaml --report '" + rep.string() + "'");
  REQUIRE(r.status == 0);
  CHECK(read_text(rep / "notes.txt") == "keep me\n");
  CHECK(fs::exists(rep / "junit.xml"));
  CHECK_FALSE(fs::exists(rep / "torque_free_asymmetric.html"));  // the earlier report's page is gone
  CHECK(fs::exists(rep / "spear1_case1.html"));
  CHECK(partial_folders(rep).empty());
}
