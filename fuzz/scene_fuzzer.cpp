// libFuzzer target for the scene reader (fuzz/README.md says how to build and run it).
//
// Property checked on every input:
//   1. read_scene_text either returns a System or throws InputError; anything else (another
//      exception, a crash, a sanitizer report, a hang) is a finding;
//   2. a System the reader accepts is written back (write_scene_text) and read again without
//      error, and the two Systems are equal field by field (the round trip the tests assert for
//      the committed scenes, here for every accepted input).
#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "tests/scene/system_equal.hpp"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  crossdyn::System scene;
  try {
    scene = crossdyn::read_scene_text(text, "fuzz.yaml");
  } catch (const crossdyn::InputError&) {
    return 0;  // rejected with a message: the expected outcome for most inputs
  }
  const std::string written = crossdyn::write_scene_text(scene);
  crossdyn::System back;
  try {
    back = crossdyn::read_scene_text(written, "fuzz.yaml");
  } catch (const crossdyn::InputError& e) {
    std::fprintf(stderr, "round trip: the written scene was rejected: %s\n--- written ---\n%s\n",
                 e.what(), written.c_str());
    std::abort();
  }
  const std::string difference = crossdyn::test::system_difference(scene, back);
  if (!difference.empty()) {
    std::fprintf(stderr, "round trip: %s differs\n--- written ---\n%s\n", difference.c_str(),
                 written.c_str());
    std::abort();
  }
  return 0;
}
