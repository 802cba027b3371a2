// Sharded verify and merge (harness/shard.hpp): the SHA-256, the slicing (stable under
// reordering, every scene in one shard, balanced), merged parts equal to an unsharded verify
// (JSON summary and JUnit XML, run times aside) with 2 and 3 shards and through GNU parallel
// (scripts/verify_parallel.sh), and the refusals of parts that do not belong together.
#include "harness/sha256.hpp"
#include "harness/shard.hpp"
#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <set>
#include <sstream>

namespace fs = std::filesystem;
using crossdyn::test::run_crossdyn;
using json = nlohmann::ordered_json;
namespace h = crossdyn::harness;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void spit(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}

// A fresh folder for one test case, removed at the end.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() / ("crossdyn_shard_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string operator/(const std::string& f) const { return (path / f).string(); }
};

// The JSON summary without its run times (each part's own; the only field that may differ).
json without_times(json j) {
  if (j.is_object()) {
    j.erase("wall_seconds");
    for (auto& [k, v] : j.items()) v = without_times(v);
  } else if (j.is_array()) {
    for (auto& v : j) v = without_times(v);
  }
  return j;
}
std::string summary_text(const fs::path& p) { return without_times(json::parse(slurp(p))).dump(1); }

// JUnit XML with the time="..." attributes (run times) blanked.
std::string junit_text(const fs::path& p) {
  static const std::regex time_attr(" time=\"[^\"]*\"");
  return std::regex_replace(slurp(p), time_attr, " time=\"-\"");
}

std::string quoted(const std::vector<std::string>& args) {
  std::string s;
  for (const std::string& a : args) s += " '" + a + "'";
  return s;
}

const std::vector<std::string> kQuick = {"torque_free_asymmetric", "spear1_case1", "chain5", "dual_spin"};

std::vector<std::string> quick_scenes() {
  std::vector<std::string> out;
  for (const std::string& s : kQuick) out.push_back(crossdyn::test::scene_path(s));
  return out;
}

// Runs N shards of verify over `scenes` into dir/part-K.json; returns the part files.
std::vector<std::string> run_shards(const TempDir& dir, const std::vector<std::string>& scenes, int n,
                                    const std::string& prefix = "part") {
  std::vector<std::string> parts;
  for (int k = 0; k < n; ++k) {
    const std::string part = dir / (prefix + "-" + std::to_string(k) + ".json");
    const auto r = run_crossdyn("verify --quiet --shard " + std::to_string(k) + "/" + std::to_string(n) +
                                " --part '" + part + "'" + quoted(scenes));
    INFO(r.output);
    REQUIRE(r.status == 0);
    parts.push_back(part);
  }
  return parts;
}

}  // namespace

TEST_CASE("sha256 matches the FIPS 180-4 test vectors", "[shard]") {
  CHECK(h::sha256_hex("") == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  CHECK(h::sha256_hex("abc") == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  CHECK(h::sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq") ==
        "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  // Lengths around the padding boundaries (55, 64 bytes) and several blocks (Python's hashlib).
  CHECK(h::sha256_hex(std::string(55, 'x')) == "d5e285683cd4efc02d021a5c62014694958901005d6f71e89e0989fac77e4072");
  CHECK(h::sha256_hex(std::string(64, 'x')) == "7ce100971f64e7001e8fe5a51973ecdfe1ced42befe7ee8d5fd6219506b5393c");
  CHECK(h::sha256_hex(std::string(1000, 'a')) == "41edece42d63e8d9bf515a9ba6932e1c20cbc9f5a5d134645adb5db1b9737ea3");
}

TEST_CASE("verify --shard K/N is zero-based and refuses bad values", "[shard]") {
  CHECK(h::parse_shard("0/1").index == 0);
  CHECK(h::parse_shard("3/4").index == 3);
  CHECK(h::parse_shard("3/4").count == 4);
  for (const char* bad : {"4/4", "1", "-1/2", "a/2", "1/0", "0/", "/3", "1/2/3"})
    CHECK_THROWS_WITH(h::parse_shard(bad), Catch::Contains("--shard") && Catch::Contains(bad));
  const auto r = run_crossdyn("verify --shard 2/2 --part /tmp/never.json chain5");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("K below N"));
  const auto no_part = run_crossdyn("verify --shard 0/2 chain5");
  CHECK(no_part.status == 2);
  CHECK_THAT(no_part.output, Catch::Contains("--part"));
}

TEST_CASE("the slicing puts every scene in one shard, balanced, whatever the order", "[shard]") {
  std::vector<std::string> scenes = crossdyn::test::committed_scenes();
  REQUIRE(scenes.size() >= 4);
  for (int n = 1; n <= 5; ++n) {
    INFO("N = " << n);
    const auto plan = h::plan_shards(scenes, n);
    std::map<std::string, int> where;
    std::vector<double> load(static_cast<std::size_t>(n), 0.0);
    double biggest = 0;
    for (const auto& s : plan) {
      REQUIRE(s.shard >= 0);
      REQUIRE(s.shard < n);
      CHECK(where.emplace(s.path, s.shard).second);  // each scene once
      CHECK(s.cost > 0);
      CHECK(s.sha256.size() == 64);
      load[static_cast<std::size_t>(s.shard)] += s.cost;
      biggest = std::max(biggest, s.cost);
    }
    CHECK(where.size() == scenes.size());
    // Longest processing time first: no shard exceeds the lightest by more than one scene.
    CHECK(*std::max_element(load.begin(), load.end()) <=
          *std::min_element(load.begin(), load.end()) + biggest);
    // Another order gives every scene the same shard.
    std::vector<std::string> other = scenes;
    std::reverse(other.begin(), other.end());
    std::mt19937 random(static_cast<unsigned>(n));
    for (int trial = 0; trial < 3; ++trial) {
      const auto again = h::plan_shards(other, n);
      for (std::size_t i = 0; i < other.size(); ++i) {
        INFO(other[i]);
        CHECK(again[i].path == other[i]);
        CHECK(again[i].shard == where.at(other[i]));
      }
      std::shuffle(other.begin(), other.end(), random);
    }
  }
}

TEST_CASE("verify --shard with 2 and 3 shards merged equals an unsharded verify on every committed scene",
          "[shard]") {
  TempDir dir("all");
  const std::vector<std::string> scenes = crossdyn::test::committed_scenes();
  const auto whole = run_crossdyn("verify --quiet --json '" + dir / "whole.json" + "' --junit '" +
                                  dir / "whole.xml" + "'" + quoted(scenes));
  INFO(whole.output);
  REQUIRE(whole.status == 0);
  for (int n : {2, 3}) {
    INFO("N = " << n);
    const std::string tag = std::to_string(n);
    std::vector<std::string> parts = run_shards(dir, scenes, n, "n" + tag);
    std::reverse(parts.begin(), parts.end());  // merge takes the parts in any order
    const auto merged = run_crossdyn("merge" + quoted(parts) + " --json '" + dir / ("m" + tag + ".json") +
                                     "' --junit '" + dir / ("m" + tag + ".xml") + "'");
    INFO(merged.output);
    REQUIRE(merged.status == 0);
    CHECK(summary_text(dir / ("m" + tag + ".json")) == summary_text(dir / "whole.json"));
    CHECK(junit_text(dir / ("m" + tag + ".xml")) == junit_text(dir / "whole.xml"));
    // Only the run times may differ: the files are byte-identical otherwise.
    CHECK(slurp(dir / ("m" + tag + ".json")).size() > 1000);
  }
}

TEST_CASE("GNU parallel runs 2 shards (scripts/verify_parallel.sh) and the merge equals verify", "[shard]") {
  REQUIRE(fs::exists("/usr/bin/parallel"));
  TempDir dir("parallel");
  const std::vector<std::string> scenes = quick_scenes();
  const auto whole = run_crossdyn("verify --quiet --json '" + dir / "whole.json" + "' --junit '" +
                                  dir / "whole.xml" + "'" + quoted(scenes));
  REQUIRE(whole.status == 0);
  const std::string cmd = "cd '" + crossdyn::test::source_dir() + "' && CROSSDYN='" +
                          crossdyn::test::binary_dir() + "/crossdyn' scripts/verify_parallel.sh 2 '" +
                          dir / "out" + "'" + quoted(scenes) + " 2>&1";
  const int status = std::system(cmd.c_str());
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
  REQUIRE(fs::exists(dir / "out/part-0.json"));
  REQUIRE(fs::exists(dir / "out/part-1.json"));
  CHECK(summary_text(dir / "out/summary.json") == summary_text(dir / "whole.json"));
  CHECK(junit_text(dir / "out/junit.xml") == junit_text(dir / "whole.xml"));
}

TEST_CASE("merge refuses parts that do not belong together, exit status 2, naming what is wrong",
          "[shard]") {
  TempDir dir("bad");
  // The scenes copied, so that one can be changed on disk.
  std::vector<std::string> scenes;
  for (const std::string& s : quick_scenes()) {
    const std::string copy = dir / fs::path(s).filename().string();
    fs::copy_file(s, copy);
    scenes.push_back(copy);
  }
  const std::vector<std::string> parts = run_shards(dir, scenes, 2);
  const auto merge = [&](const std::vector<std::string>& ps) {
    return run_crossdyn("merge --quiet" + quoted(ps) + " --json '" + dir / "m.json" + "'");
  };
  REQUIRE(merge(parts).status == 0);
  const json part0 = json::parse(slurp(parts[0]));

  SECTION("another crossdyn version") {
    json j = part0;
    j["version"] = "0.0.1 (git deadbee)";
    spit(dir / "old.json", j.dump());
    const auto r = merge({dir / "old.json", parts[1]});
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("written by crossdyn 0.0.1 (git deadbee)") &&
                             Catch::Contains("old.json"));
  }
  SECTION("a scene hash that differs between parts") {
    json j = part0;
    j["scenes"][1]["sha256"] = std::string(64, '0');
    spit(dir / "changed.json", j.dump());
    const auto r = merge({dir / "changed.json", parts[1]});
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("changed between the shards") &&
                             Catch::Contains(j["scenes"][1]["path"].get<std::string>()));
  }
  SECTION("a scene file changed on disk since the shards ran") {
    std::ofstream(scenes[2], std::ios::app) << "\n# edited\n";
    const auto r = merge(parts);
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("changed since the parts were written") &&
                             Catch::Contains(scenes[2]));
  }
  SECTION("a missing shard") {
    const auto r = merge({parts[1]});
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("missing shard 0/2"));
  }
  SECTION("a duplicated shard") {
    fs::copy_file(parts[1], dir / "again.json");
    const auto r = merge({parts[0], parts[1], dir / "again.json"});
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("shard 1/2 is given 2 times") && Catch::Contains(parts[1]) &&
                             Catch::Contains("again.json"));
  }
  SECTION("parts of different N") {
    const std::vector<std::string> three = run_shards(dir, scenes, 3, "three");
    const auto r = merge({parts[0], parts[1], three[2]});
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("different shard counts") && Catch::Contains("2/3"));
  }
  SECTION("a file that is not a part") {
    spit(dir / "junk.json", "{\"tool\": \"crossdyn\"}");
    const auto r = merge({parts[0], dir / "junk.json"});
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("junk.json") && Catch::Contains("not a crossdyn part file"));
  }
}
