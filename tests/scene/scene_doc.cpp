// crossdyn_scene_doc: prints or rewrites what is generated from the scene schema
// (core/scene/schema.hpp), so that the documentation and the fuzz dictionary cannot drift from it.
//
//   crossdyn_scene_doc --markdown              the key reference of docs/scene-format.md
//   crossdyn_scene_doc --dict                  fuzz/scene.dict
//   crossdyn_scene_doc --write-docs FILE       replaces the generated block of FILE
//   crossdyn_scene_doc --write-dict FILE       rewrites FILE
//   crossdyn_scene_doc --pin SCENE.yaml        the pin of a new scene (tests/scene/pinned/)
// tests/scene/test_scene_docs.cpp and test_schema.cpp fail while the committed files differ.
#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "core/scene/schema.hpp"
#include "tests/scene/generated_block.hpp"

#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (argc == 2 && mode == "--markdown") {
    std::cout << crossdyn::scene::markdown_reference();
    return 0;
  }
  if (argc == 2 && mode == "--dict") {
    std::cout << crossdyn::scene::fuzz_dictionary();
    return 0;
  }
  if (argc == 3 && mode == "--pin") {
    try {
      std::cout << crossdyn::write_scene_text(crossdyn::read_scene(argv[2]));
    } catch (const crossdyn::InputError& e) {
      std::cerr << e.what() << '\n';
      return 2;
    }
    return 0;
  }
  if (argc == 3 && (mode == "--write-docs" || mode == "--write-dict")) {
    std::string text = crossdyn::scene::fuzz_dictionary();
    if (mode == "--write-docs") {
      std::ifstream in(argv[2]);
      std::stringstream ss;
      ss << in.rdbuf();
      text = ss.str();
      if (!crossdyn::test::replace_generated_block(text, crossdyn::scene::markdown_reference())) {
        std::cerr << argv[2] << ": no generated block (" << crossdyn::test::kBeginMarker << " ... "
                  << crossdyn::test::kEndMarker << ")\n";
        return 2;
      }
    }
    std::ofstream(argv[2]) << text;
    return 0;
  }
  std::cerr << "usage: crossdyn_scene_doc --markdown | --dict | --write-docs FILE | --write-dict FILE | --pin SCENE\n";
  return 2;
}
