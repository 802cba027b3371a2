// The generated block of docs/scene-format.md: the text between two marker lines, written by
// tests/scene/scene_doc.cpp and checked by tests/scene/test_scene_docs.cpp.
#pragma once

#include <optional>
#include <string>

namespace crossdyn::test {

inline const char* const kBeginMarker = "<!-- BEGIN GENERATED KEY REFERENCE -->";
inline const char* const kEndMarker = "<!-- END GENERATED KEY REFERENCE -->";

// The text between the marker lines (without them), or nothing when a marker is missing.
inline std::optional<std::string> generated_block(const std::string& text) {
  const std::size_t b = text.find(kBeginMarker);
  const std::size_t e = text.find(kEndMarker);
  if (b == std::string::npos || e == std::string::npos || e < b) return std::nullopt;
  const std::size_t start = text.find('\n', b);
  if (start == std::string::npos || start + 1 > e) return std::nullopt;
  return text.substr(start + 1, e - start - 1);
}

// Replaces that text by `block`; false when a marker is missing.
inline bool replace_generated_block(std::string& text, const std::string& block) {
  const std::size_t b = text.find(kBeginMarker);
  const std::size_t e = text.find(kEndMarker);
  if (b == std::string::npos || e == std::string::npos || e < b) return false;
  const std::size_t start = text.find('\n', b) + 1;
  text.replace(start, e - start, block);
  return true;
}

}  // namespace crossdyn::test
