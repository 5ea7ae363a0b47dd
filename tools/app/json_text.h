// json_text.h - the JSON text that esim writes to its files and prints.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "sim/message_text.h"

namespace esim::app {

// j as text (indent < 0: one line). A byte that is not UTF-8 (an environment variable such as
// LP_NUM_THREADS, a file name) becomes U+FFFD: nlohmann's default throws, which ended a run
// with exit 4 after every frame was computed, leaving only DIR.partial/
inline std::string jsonText(const nlohmann::json& j, int indent = -1) {
  return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

// a value read from a file, as an error message shows it: its one-line JSON text, or that
// text's start and length when it is long (a list of a million entries where an object was
// expected was dumped whole into the message)
inline std::string jsonInMessage(const nlohmann::json& j) { return nameInMessage(jsonText(j)); }

}  // namespace esim::app
