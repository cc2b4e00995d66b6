// The command line of a tool, parsed with CLI11 the same way in every tool:
// - `--help` prints the tool's description and every flag with its unit and default, exit 0;
// - an unknown flag, a missing or a malformed value, or a missing required flag prints
//   "TOOL: --flag: problem" on stderr and exits 2 (kUsageExitStatus), before any work;
// - numbers are strict: `--epochs 10x`, `--lr nan` or `--count -1` into an unsigned are errors.
#pragma once

#include <CLI/CLI.hpp>
#include <charconv>
#include <cmath>
#include <optional>
#include <string>
#include <system_error>
#include <type_traits>
#include <vector>

namespace deep_ois {

// Exit status of every tool for a command line it cannot use.
constexpr int kUsageExitStatus = 2;

// `text` as a T when all of it is one decimal number that fits T: a whole number for integer
// types (no sign for unsigned ones), a finite number for floating point ones (1e-4 is fine).
template <typename T>
std::optional<T> parseStrictNumber(const std::string& text) {
  static_assert(std::is_arithmetic_v<T> && !std::is_same_v<T, bool>, "a number type");
  const char* begin = text.data();
  const char* const end = text.data() + text.size();
  // from_chars takes no '+', and a '-' into an unsigned type wraps with some parsers: say no.
  if (begin != end && *begin == '+') ++begin;
  if (begin == end || (std::is_unsigned_v<T> && *begin == '-')) return std::nullopt;
  T value{};
  const auto [stop, error] = std::from_chars(begin, end, value);
  if (error != std::errc() || stop != end) return std::nullopt;
  if constexpr (std::is_floating_point_v<T>) {
    if (!std::isfinite(value)) return std::nullopt;
  }
  return value;
}

// A CLI11 validator that accepts exactly what parseStrictNumber<T> accepts. ToolCommandLine's
// addNumber attaches it; use it directly on list options (`->delimiter(',')`).
template <typename T>
CLI::Validator strictNumber() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        if (parseStrictNumber<T>(text)) return {};
        return "Value " + text + " could not be converted to " +
               (std::is_integral_v<T>
                    ? (std::is_unsigned_v<T> ? "a whole number >= 0" : "a whole number")
                    : "a finite number");
      },
      "");
}

// `count` comma-separated numbers, e.g. a row-major 3x3 matrix "1,0,0,0,1,0,0,0,1" (count 9).
CLI::Validator commaSeparatedNumbers(std::size_t count);
// The numbers of a text that commaSeparatedNumbers accepted.
std::vector<double> splitCommaSeparatedNumbers(const std::string& text);
// One of the given words, e.g. {"on", "off"}; the error lists them.
CLI::Validator oneOf(const std::vector<std::string>& words);
// A number >= minimum (atLeast) or > bound (greaterThan), e.g. atLeast(1) for a count of frames.
// Put after strictNumber (addNumber does), which rejects what is not a number at all.
CLI::Validator atLeast(double minimum);
CLI::Validator greaterThan(double bound);
// A file (a folder) that exists, checked before the tool starts; the error names the flag.
CLI::Validator existingFile();
CLI::Validator existingDirectory();

// One tool's command line. Declare the flags on app() (or with addNumber), then
//   if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
// Checks across flags after parsing end with `return command_line.usageError("...")`.
class ToolCommandLine {
 public:
  // `description`: the one paragraph --help prints first; `footer`: what it prints after the
  // flags (exit statuses, file formats), may be empty.
  ToolCommandLine(const std::string& tool, const std::string& description,
                  const std::string& footer = "");

  CLI::App& app() { return app_; }
  const std::string& tool() const { return tool_; }

  // A numeric flag: strict (see parseStrictNumber), its default shown by --help.
  template <typename T>
  CLI::Option* addNumber(const std::string& flag, T& value, const std::string& description) {
    return app_.add_option(flag, value, description)
        ->check(strictNumber<T>())
        ->capture_default_str();
  }

  // Parses argv[1..argc). Returns nothing when the tool should go on; otherwise the exit status
  // to return at once, the help or the error already printed (0 after --help, 2 on an error).
  // Run without any argument, a tool with required flags prints its help on stderr and exits 2.
  std::optional<int> parse(int argc, const char* const* argv);
  // The same for arguments already split, the program name first (e.g. after ros::removeROSArgs).
  std::optional<int> parse(const std::vector<std::string>& arguments);

  // A problem found after parsing (flags that do not go together): prints "TOOL: problem" and
  // where to find the usage on stderr; returns kUsageExitStatus.
  int usageError(const std::string& problem) const;

  // What --help prints.
  std::string help() const { return app_.help(); }

 private:
  std::string tool_;
  CLI::App app_;
};

}  // namespace deep_ois
