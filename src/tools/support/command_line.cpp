#include "deep_ois/tools/support/command_line.h"

#include <cstdio>
#include <sstream>

namespace deep_ois {
namespace {

std::string join(const std::vector<std::string>& words, const std::string& separator) {
  std::string text;
  for (std::size_t i = 0; i < words.size(); ++i) text += (i ? separator : "") + words[i];
  return text;
}

}  // namespace

std::vector<double> splitCommaSeparatedNumbers(const std::string& text) {
  std::vector<double> numbers;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    const std::optional<double> number = parseStrictNumber<double>(item);
    if (!number) throw std::invalid_argument("'" + item + "' is not a number");
    numbers.push_back(*number);
  }
  // getline drops an empty last item ("1,2,"): count the commas instead of trusting it.
  if (!text.empty() && text.back() == ',')
    throw std::invalid_argument("a number after the last comma");
  return numbers;
}

CLI::Validator commaSeparatedNumbers(std::size_t count) {
  return CLI::Validator(
      [count](std::string& text) -> std::string {
        try {
          const std::size_t found = splitCommaSeparatedNumbers(text).size();
          if (found == count) return {};
          return "needs " + std::to_string(count) + " comma-separated numbers, got " +
                 std::to_string(found) + " in '" + text + "'";
        } catch (const std::invalid_argument& e) {
          return "needs " + std::to_string(count) + " comma-separated numbers, got '" + text +
                 "' (" + e.what() + ")";
        }
      },
      "");
}

CLI::Validator oneOf(const std::vector<std::string>& words) {
  return CLI::Validator(
      [words](std::string& text) -> std::string {
        for (const std::string& word : words) {
          if (text == word) return {};
        }
        return "must be " + join(words, " or ") + ", got '" + text + "'";
      },
      "");
}

namespace {

// "3", "0.5", "1e-05": a bound as people write it.
std::string shortNumber(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

CLI::Validator boundCheck(double bound, bool inclusive) {
  return CLI::Validator(
      [bound, inclusive](std::string& text) -> std::string {
        const std::optional<double> value = parseStrictNumber<double>(text);
        if (value && (inclusive ? *value >= bound : *value > bound)) return {};
        return std::string("must be ") + (inclusive ? ">= " : "> ") + shortNumber(bound) +
               ", got " + text;
      },
      "");
}

// Help lines of the description at most this wide (CLI11 2.1 prints the text as it is given).
constexpr std::size_t kHelpWidth = 100;

std::string wrap(const std::string& paragraph) {
  std::istringstream words(paragraph);
  std::string word, line, text;
  while (words >> word) {
    if (!line.empty() && line.size() + 1 + word.size() > kHelpWidth) {
      text += line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  return text + line;
}

}  // namespace

CLI::Validator atLeast(double minimum) { return boundCheck(minimum, true); }
CLI::Validator greaterThan(double bound) { return boundCheck(bound, false); }

CLI::Validator existingFile() {
  // CLI11's own check, without the ":FILE" it would add to the flag's line of the help.
  CLI::Validator check = CLI::ExistingFile;
  return check.description("");
}

CLI::Validator existingDirectory() {
  CLI::Validator check = CLI::ExistingDirectory;
  return check.description("");
}

ToolCommandLine::ToolCommandLine(const std::string& tool, const std::string& description,
                                 const std::string& footer)
    : tool_(tool), app_(wrap(description) + "\n", tool) {
  if (!footer.empty()) app_.footer(footer);
  app_.get_formatter()->column_width(36);
}

std::optional<int> ToolCommandLine::parse(const std::vector<std::string>& arguments) {
  std::vector<const char*> argv;
  for (const std::string& argument : arguments) argv.push_back(argument.c_str());
  argv.push_back(nullptr);
  return parse(static_cast<int>(arguments.size()), argv.data());
}

std::optional<int> ToolCommandLine::parse(int argc, const char* const* argv) {
  // An unknown flag first, by its name: CLI11 would otherwise report a neighbouring problem
  // first (e.g. the value after it taken for a malformed positional argument).
  for (int i = 1; i < argc; ++i) {
    const std::string argument = argv[i];
    if (argument == "--") break;
    if (argument.rfind("--", 0) != 0) continue;
    const std::string flag = argument.substr(0, argument.find('='));
    if (app_.get_option_no_throw(flag) == nullptr) return usageError(flag + ": unknown flag");
  }
  try {
    app_.parse(argc, argv);
    return std::nullopt;
  } catch (const CLI::CallForHelp&) {
    std::fputs(help().c_str(), stdout);
    return 0;
  } catch (const CLI::CallForAllHelp&) {
    std::fputs(help().c_str(), stdout);
    return 0;
  } catch (const CLI::RequiredError& e) {
    if (argc <= 1) {
      std::fputs(help().c_str(), stderr);
      return kUsageExitStatus;
    }
    return usageError(e.what());
  } catch (const CLI::ExtrasError&) {
    return usageError("unexpected argument(s): " + join(app_.remaining(), " "));
  } catch (const CLI::ParseError& e) {
    return usageError(e.what());
  }
}

int ToolCommandLine::usageError(const std::string& problem) const {
  std::fprintf(stderr, "%s: %s\nRun '%s --help' for the flags.\n", tool_.c_str(), problem.c_str(),
               tool_.c_str());
  return kUsageExitStatus;
}

}  // namespace deep_ois
