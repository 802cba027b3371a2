// Text helpers of the scene reader and writer (internal to core/: also the flexible-body data readers).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace crossdyn::scene {

// x in its shortest form that reads back to the same double (std::to_chars).
std::string shortest(double x);

// 's' quoted, at most 40 characters, control characters shown as '?'.
std::string quoted_excerpt(const std::string& s);

// "a, b, c" (at most max_items, then ", ...").
std::string join(const std::vector<std::string>& v, std::size_t max_items = 12);

// Optimal-string-alignment distance (Levenshtein plus adjacent transpositions), ignoring case.
std::size_t edit_distance(const std::string& a, const std::string& b);

// A schema noun without its leading article ("a motion profile" => "motion profile"), for messages
// that put their own word before it ("unknown motion profile 'x'").
std::string without_article(const std::string& noun);

// " (did you mean 'x'?)" when one candidate is close to `word`, else "".
std::string suggestion(const std::string& word, const std::vector<std::string>& candidates);

// Position of the first byte that is not valid UTF-8 (strict: no overlong forms, no surrogates,
// nothing above U+10FFFF), or npos.
std::size_t invalid_utf8_at(std::string_view s);

}  // namespace crossdyn::scene
