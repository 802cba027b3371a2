// Messages for unknown names (see names.hpp).
#include "core/names.hpp"

#include "core/scene/text.hpp"

namespace crossdyn {

std::string unknown_name_text(std::string_view noun, std::string_view s,
                              const std::vector<std::string>& known) {
  const std::string word(s);
  std::string list;
  for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
  return "unknown " + std::string(noun) + " " + scene::quoted_excerpt(word) +
         scene::suggestion(word, known) + "; known: " + list;
}

}  // namespace crossdyn
