// printf-style formatting into a std::string, for report lines and diagnostics values.
//
// Why one helper: several reports and nodes formatted a number with a fixed-size char buffer
// each; this one sizes the buffer to the text, so a long value is never cut.
#pragma once

#include <cstdio>
#include <string>

namespace deep_ois {

// `pattern` is a printf format whose conversions match `values` (the compiler checks them
// when the pattern is a literal, through the format attribute of the std::snprintf calls).
template <typename... Values>
std::string printfText(const char* pattern, Values... values) {
  const int length = std::snprintf(nullptr, 0, pattern, values...);
  if (length <= 0) return std::string();
  std::string text(static_cast<std::size_t>(length) + 1, '\0');
  std::snprintf(&text[0], text.size(), pattern, values...);
  text.resize(static_cast<std::size_t>(length));
  return text;
}

}  // namespace deep_ois
